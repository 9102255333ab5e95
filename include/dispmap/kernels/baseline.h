#pragma once
// The traditional baseline's tangent space (baseline.h; Nießner & Loop 2013, Fig. 7: a UV
// height texture plus a tangent-space normal map, as engines ship them).
//
// Frame: N the unit base normal, T = normalize(s_u - N (N . s_u)) the face's u direction made
// perpendicular to N (the per-face atlas), or the UV layout's s direction made perpendicular
// (dmUvTangent: the mesh-UV layout), B = N x T. (T, B, N) is right-handed and orthonormal; a normal n is
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

// The mesh's UV at face (u, v) = faceUV as an engine interpolates it over a patch: bilinear
// between the face's corner UVs c01 = (c0, c1), c23 = (c2, c3) at (u, v) = (0, 0), (1, 0),
// (1, 1), (0, 1); du, dv its derivatives along u and v.
DM_TFUNC rvec2 dmFaceUv(rvec4 c01, rvec4 c23, rvec2 faceUV, DM_OUT(rvec2) du, DM_OUT(rvec2) dv) {
    rvec2 c0 = rvec2(c01.x, c01.y);
    rvec2 c1 = rvec2(c01.z, c01.w);
    rvec2 c2 = rvec2(c23.x, c23.y);
    rvec2 c3 = rvec2(c23.z, c23.w);
    real u = faceUV.x;
    real v = faceUV.y;
    du = (c1 - c0) * (real(1) - v) + (c2 - c3) * v;
    dv = (c3 - c0) * (real(1) - u) + (c2 - c1) * u;
    return (c0 * (real(1) - u) + c1 * u) * (real(1) - v) + (c3 * (real(1) - u) + c2 * u) * v;
}

// Texture coordinate of UV (s, t) in an image whose row 0 is t = 1 (image files' top row;
// Vulkan's texture coordinate y = 0).
DM_TFUNC rvec2 dmUvTexcoord(rvec2 st) {
    return rvec2(st.x, real(1) - st.y);
}

// The conventional tangent of a UV layout: the direction of increasing s on the surface,
// dP/ds = (P_u t_v - P_v t_u) / det (su = P_u, sv = P_v; uvDu = (s_u, t_u), uvDv = (s_v, t_v);
// det = s_u t_v - s_v t_u the UV map's Jacobian), made perpendicular to N and normalised
// by dmTangentFromDerivative (which also covers a degenerate UV map). Only the sign of det
// matters for the direction, so it is not divided by.
DM_TFUNC rvec3 dmUvTangent(rvec3 su, rvec3 sv, rvec2 uvDu, rvec2 uvDv, rvec3 N) {
    real det = uvDu.x * uvDv.y - uvDv.x * uvDu.y;
    rvec3 ps = su * uvDv.y - sv * uvDu.y;
    return dmTangentFromDerivative(det < real(0) ? -ps : ps, N);
}

// The tangent of a face of the mesh-UV layout at face (u, v) = faceUV: its four corner
// tangents t0..t3 (per-vertex tangents at (0, 0), (1, 0), (1, 1), (0, 1)) interpolated
// bilinearly, as a shader interpolates a vertex attribute, then made perpendicular to N and
// normalised (dmTangentFromDerivative).
DM_TFUNC rvec3 dmFaceTangent(rvec3 t0, rvec3 t1, rvec3 t2, rvec3 t3, rvec2 faceUV, rvec3 N) {
    real u = faceUV.x;
    real v = faceUV.y;
    rvec3 t = (t0 * (real(1) - u) + t1 * u) * (real(1) - v) + (t3 * (real(1) - u) + t2 * u) * v;
    return dmTangentFromDerivative(t, N);
}
// dispmap:glsl-end
} // namespace dispmap::kern
#include "dispmap/kernels/prelude_end.h"
