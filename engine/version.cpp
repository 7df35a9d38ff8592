#include <hindsight/engine/types.h>
#include <hindsight/version.h>

namespace hindsight {

// The version is set once, in CMakeLists.txt's project(); <hindsight/version.h> is generated from it.
const char* version() { return HINDSIGHT_VERSION_STRING; }

}  // namespace hindsight
