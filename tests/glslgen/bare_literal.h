// A kernel header the generator must refuse (tests/CMakeLists.txt names the expected error).
#include "dispmap/kernels/prelude.h"
namespace dispmap::kern {
// dispmap:glsl-begin
DM_TFUNC real dmHalf(real x) {
    return x * 0.5;
}
// dispmap:glsl-end
} // namespace dispmap::kern
