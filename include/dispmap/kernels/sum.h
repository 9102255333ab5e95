#pragma once
// Sums in a fixed order. GLSL's dot() and matrix-vector products leave the order of their
// additions to the implementation: lavapipe's differs from GLM's, which made the biquadratic
// differ by up to 4 ULP of its coefficients (measured by `dispmap parity` before these
// existed). Kernels that promise bit parity spell their sums out with these.
#include "dispmap/kernels/prelude.h"

namespace dispmap::kern {
// dispmap:glsl-begin double
// a.x b.x + a.y b.y + a.z b.z, added left to right.
DM_TFUNC real dmDot3(rvec3 a, rvec3 b) {
    return (a.x * b.x + a.y * b.y) + a.z * b.z;
}

// The cross product a x b, each component the difference of two products (GLSL's cross()
// leaves its evaluation to the implementation).
DM_TFUNC rvec3 dmCross3(rvec3 a, rvec3 b) {
    return rvec3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}

// The matrix-vector product m b (columns of m weighted by b), added left to right.
DM_TFUNC rvec3 dmMulMV3(rmat3 m, rvec3 b) {
    return (m[0] * b.x + m[1] * b.y) + m[2] * b.z;
}
// dispmap:glsl-end
} // namespace dispmap::kern
#include "dispmap/kernels/prelude_end.h"
