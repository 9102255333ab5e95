// A kernel header the generator must refuse (tests/CMakeLists.txt names the expected error).
#include "dispmap/kernels/prelude.h"
namespace dispmap::kern {
// dispmap:glsl-begin
DM_FUNC int dmA(int n) {
    return n > 0 ? dmB(n - 1) : 0;
}
DM_FUNC int dmB(int n) {
    return dmA(n);
}
// dispmap:glsl-end
} // namespace dispmap::kern
