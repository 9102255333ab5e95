// A kernel header the generator must refuse (tests/CMakeLists.txt names the expected error).
#include "dispmap/kernels/prelude.h"
namespace dispmap::kern {
// dispmap:glsl-begin
DM_TFUNC real half(real x) {
    return x / real(2);
}
// dispmap:glsl-end
} // namespace dispmap::kern
