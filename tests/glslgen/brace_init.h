// A kernel header the generator must refuse (tests/CMakeLists.txt names the expected error).
#include "dispmap/kernels/prelude.h"
namespace dispmap::kern {
// dispmap:glsl-begin
DM_TFUNC rvec2 dmPair(real x) {
    rvec2 p{x, x};
    return p;
}
// dispmap:glsl-end
} // namespace dispmap::kern
