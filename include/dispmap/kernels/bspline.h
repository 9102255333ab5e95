#pragma once
// Uniform quadratic B-spline basis on one knot interval, with derivatives.
// Source: Nießner & Loop 2013, §3 and §5.1 (B_i^2 of the biquadratic displacement function).
#include "dispmap/kernels/prelude.h"

namespace dispmap::kern {
// dispmap:glsl-begin double
// The three uniform quadratic B-spline basis functions that are non-zero on one knot
// interval, at t in [0, 1]: ((1-t)^2/2, 1/2 + t(1-t), t^2/2). They sum to 1 for every t.
DM_TFUNC rvec3 dmBSpline2(real t) {
    real s = real(1) - t;
    return rvec3(real(0.5) * s * s, real(0.5) + t * s, real(0.5) * t * t);
}

// First derivatives d/dt of dmBSpline2: (t - 1, 1 - 2t, t). They sum to 0.
DM_TFUNC rvec3 dmBSpline2D1(real t) {
    return rvec3(t - real(1), real(1) - real(2) * t, t);
}

// All three orders at once, as the columns of a matrix: column 0 the values (dmBSpline2),
// column 1 the first derivatives (dmBSpline2D1), column 2 the second derivatives, which are
// (1, -2, 1) on the whole interval.
DM_TFUNC rmat3 dmBSpline2Derivs(real t) {
    return rmat3(dmBSpline2(t), dmBSpline2D1(t), rvec3(real(1), real(-2), real(1)));
}
// dispmap:glsl-end
} // namespace dispmap::kern
#include "dispmap/kernels/prelude_end.h"
