#pragma once
// The traditional baseline's tangent space (baseline.h; Nießner & Loop 2013, Fig. 7: a UV
// height texture plus a tangent-space normal map, as engines ship them).
//
// Frame: N the unit base normal, T = normalize(s_u - N (N . s_u)) the face's u direction made
// perpendicular to N, B = N x T. (T, B, N) is right-handed and orthonormal; a normal n is
// stored as n_ts = (n . T, n . B, n . N) and read back as normalize(n_ts.x T + n_ts.y B +
// n_ts.z N). A shader that interpolates T and N from the vertices re-orthonormalises them
// first: N = normalize(N), T = dmTangentFromDerivative(T, N).
//
// Atlas addressing: face f's chart has (n + 1) x (n + 1) texels with texel (i, j) at face
// (u, v) = (i / n, j / n); with the chart's first texel at `origin` the texture coordinate of
// (u, v) is (origin + 0.5 + (u, v) n) / size, so linear filtering interpolates between the
// texels around (u, v) within the chart and never reads a neighbouring chart.
#include "dispmap/kernels/sum.h"
#include "dispmap/kernels/normal.h"
#include "dispmap/kernels/prelude.h"

namespace dispmap::kern {
// dispmap:glsl-begin double
// T: su with its component along the unit normal N removed (twice: the second pass removes
// what cancellation left when su is nearly parallel to N), normalised. Where less than 1e-6
// of |su| is left (su zero or parallel to N), a unit vector perpendicular to N built from the
// coordinate axis least aligned with it (x unless |N.x| > 0.9, then y).
DM_TFUNC rvec3 dmTangentFromDerivative(rvec3 su, rvec3 N) {
    rvec3 t = su - N * dmDot3(N, su);
    t = t - N * dmDot3(N, t);
    real l2 = dmDot3(t, t);
    if (l2 > real(1e-12) * dmDot3(su, su)) {
        return t * (real(1) / sqrt(l2));
    }
    rvec3 a = abs(N.x) > real(0.9) ? rvec3(real(0), real(1), real(0)) : rvec3(real(1), real(0), real(0));
    rvec3 p = a - N * dmDot3(N, a);
    return p * (real(1) / sqrt(dmDot3(p, p)));
}

// n in the frame (T, B = N x T, N): (n . T, n . B, n . N).
DM_TFUNC rvec3 dmTangentSpaceEncode(rvec3 n, rvec3 T, rvec3 N) {
    rvec3 B = cross(N, T);
    return rvec3(dmDot3(n, T), dmDot3(n, B), dmDot3(n, N));
}

// The world normal of a tangent-space normal: normalize(nts.x T + nts.y B + nts.z N), N where
// nts is zero.
DM_TFUNC rvec3 dmTangentSpaceDecode(rvec3 nts, rvec3 T, rvec3 N) {
    rvec3 B = cross(N, T);
    return dmSafeNormalize((T * nts.x + B * nts.y) + N * nts.z, N);
}

// A normal-map texel read through an 8-bit UNORM view (c in [0, 1]^3) back to [-1, 1]^3.
DM_TFUNC rvec3 dmUnpackUnormNormal(rvec3 c) {
    return c * real(2) - rvec3(real(1));
}

// Texture coordinate of face (u, v) = faceUV in a chart of n x n texel intervals whose first
// texel is at `origin` (texels) in an atlas of `size` texels (see the top of this file).
DM_TFUNC rvec2 dmBaselineAtlasUV(rvec2 origin, rvec2 faceUV, real n, rvec2 size) {
    return (origin + rvec2(real(0.5)) + faceUV * n) / size;
}
// dispmap:glsl-end
} // namespace dispmap::kern
#include "dispmap/kernels/prelude_end.h"
