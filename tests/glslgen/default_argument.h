// A kernel header the generator must refuse (tests/CMakeLists.txt names the expected error).
#include "dispmap/kernels/prelude.h"
namespace dispmap::kern {
// dispmap:glsl-begin
DM_TFUNC real dmScale(real x, int n = 2) {
    return x * real(n);
}
// dispmap:glsl-end
} // namespace dispmap::kern
