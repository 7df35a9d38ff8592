#include "engine/types.h"

namespace hindsight {

const char* version() { return "0.1.0"; }

}  // namespace hindsight
