// A kernel header the generator must refuse (tests/CMakeLists.txt names the expected error).
#include "dispmap/kernels/prelude.h"
namespace dispmap::kern {
// dispmap:glsl-begin
DM_TFUNC rvec2 dmZero(int n) {
    return rvec2(real(n));
}
// dispmap:glsl-end
} // namespace dispmap::kern
