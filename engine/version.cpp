#include <hindsight/engine/types.h>

namespace hindsight {

// HINDSIGHT_VERSION comes from CMakeLists.txt, the one place the version is set.
const char* version() { return HINDSIGHT_VERSION; }

}  // namespace hindsight
