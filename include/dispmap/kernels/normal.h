#pragma once
// Normals of the base and the displaced surface (Nießner & Loop 2013, §5.1, §5.2, §5.4;
// checked against finite differences and the cross-product route in tests/test_surface.cpp).
//
//   f = s + N D,   f_u = s_u + N_u D + N D_u,   f_v likewise,   N_f = f_u x f_v / |f_u x f_v|
//
// Accurate normals keep the Weingarten term N_u D (§5.1); approximate normals drop it (Blinn,
// §5.2). N_u, N_v come from the Weingarten equations (do Carmo §3-3), which give the
// derivatives of the unit normal directly:
//   N_u = [(fF - eG) s_u + (eF - fE) s_v] / (EG - F^2),   N_v = [(gF - fG) s_u + (fF - gE) s_v] / (EG - F^2).
// The paper then applies N_u <- (N*_u - N (N*_u . N)) / |N*| to the Weingarten result; that
// step belongs to the derivative of the unnormalised normal N* = s_u x s_v (the cross route,
// dmNormalDerivCross below), and applied to the Weingarten result it would divide a unit-normal
// derivative by |N*| once more. The tests check both routes against finite differences.
//
// Numerics. EG - F^2 is evaluated as |s_u x s_v|^2, the same number without the cancellation
// of the dot-product form, and bounded below by (sinMin |s_u| |s_v|)^2: where the angle between
// s_u and s_v falls under asin(sinMin) the Weingarten term is damped, never amplified further
// (a near-singular parameterisation only amplifies rounding there; the true N_u stays bounded
// by the curvature). Where s_u x s_v vanishes the normal falls back to the first-order Taylor
// term towards the inside of the face, +-n_u +- n_v (OpenSubdiv uses n_u + n_v), then to the
// caller's fallback; N_u = N_v = 0 there. No kernel here returns NaN for finite input of
// moderate size (|s_u|^2 |s_v|^2 must not overflow).
#include "dispmap/kernels/sum.h"
#include "dispmap/kernels/prelude.h"

namespace dispmap::kern {
// dispmap:glsl-begin double
// v / |v|, or `fallback` where |v|^2 is zero (or underflows).
DM_TFUNC rvec3 dmSafeNormalize(rvec3 v, rvec3 fallback) {
    real l2 = dmDot3(v, v);
    if (l2 > real(0)) {
        return v * (real(1) / sqrt(l2));
    }
    return fallback;
}

// The unit normal of s at (u, v) from its first derivatives, with the degenerate fallbacks
// described above (second derivatives are needed only there). Where s_u x s_v vanishes the
// normal is the limit from inside the face: n(u + du, v + dv) ~ du n_u + dv n_v with (du, dv)
// pointing into [0, 1]^2 from (u, v), so a degenerate point at u = 1 or v = 1 is not flipped.
DM_TFUNC rvec3 dmBaseNormal(rvec3 su, rvec3 sv, rvec3 suu, rvec3 suv, rvec3 svv, rvec2 uv, rvec3 fallback) {
    rvec3 n = cross(su, sv);
    real l2 = dmDot3(n, n);
    if (l2 > real(0)) {
        return n * (real(1) / sqrt(l2));
    }
    real du = uv.x < real(0.5) ? real(1) : real(-1);
    real dv = uv.y < real(0.5) ? real(1) : real(-1);
    rvec3 taylor = (cross(suu, sv) + cross(su, suv)) * du + (cross(suv, sv) + cross(su, svv)) * dv;
    return dmSafeNormalize(taylor, fallback);
}

// Weingarten equations (§5.1): N_u and N_v of the unit normal N of s. sinMin bounds the
// first fundamental form below (see the header comment); the library passes 1e-3 in float and
// 1e-7 in double (displaced_surface.h, kSinMin).
DM_TFUNC void dmNormalDerivWeingarten(rvec3 su, rvec3 sv, rvec3 suu, rvec3 suv, rvec3 svv, rvec3 N, real sinMin,
                                      DM_OUT(rvec3) Nu, DM_OUT(rvec3) Nv) {
    rvec3 n = cross(su, sv);
    real E = dmDot3(su, su);
    real F = dmDot3(su, sv);
    real G = dmDot3(sv, sv);
    real det = max(dmDot3(n, n), (sinMin * sinMin) * (E * G));
    real e = dmDot3(N, suu);
    real f = dmDot3(N, suv);
    real g = dmDot3(N, svv);
    if (det > real(0)) {
        Nu = (su * (f * F - e * G) + sv * (e * F - f * E)) / det;
        Nv = (su * (g * F - f * G) + sv * (f * F - g * E)) / det;
    } else {
        Nu = rvec3(real(0));
        Nv = rvec3(real(0));
    }
}

// The cross-product route (OpenSubdiv's osd/glslPatchCommon.glsl):
// n = s_u x s_v, n_u = s_uu x s_v + s_u x s_uv, N_u = (n_u - N (N . n_u)) / |n|. Used as the
// independent check of the Weingarten route; |n| is bounded below as there.
DM_TFUNC void dmNormalDerivCross(rvec3 su, rvec3 sv, rvec3 suu, rvec3 suv, rvec3 svv, rvec3 N, real sinMin,
                                 DM_OUT(rvec3) Nu, DM_OUT(rvec3) Nv) {
    rvec3 n = cross(su, sv);
    real len = sqrt(max(dmDot3(n, n), (sinMin * sinMin) * (dmDot3(su, su) * dmDot3(sv, sv))));
    rvec3 nu = cross(suu, sv) + cross(su, suv);
    rvec3 nv = cross(suv, sv) + cross(su, svv);
    if (len > real(0)) {
        Nu = (nu - N * dmDot3(N, nu)) / len;
        Nv = (nv - N * dmDot3(N, nv)) / len;
    } else {
        Nu = rvec3(real(0));
        Nv = rvec3(real(0));
    }
}

// Approximate displaced frame (§5.2): f_u = s_u + N D_u, f_v = s_v + N D_v, with
// d1 = (D, D_u, D_v) in the face's parameters. Returns the unit normal (N where the frame
// degenerates, e.g. where a large displacement folds the surface onto itself).
DM_TFUNC rvec3 dmDisplacedNormalApprox(rvec3 su, rvec3 sv, rvec3 N, rvec3 d1, DM_OUT(rvec3) fu, DM_OUT(rvec3) fv) {
    fu = su + N * d1.y;
    fv = sv + N * d1.z;
    return dmSafeNormalize(cross(fu, fv), N);
}

// Accurate displaced frame (§5.1): f_u = s_u + N_u D + N D_u, f_v likewise.
DM_TFUNC rvec3 dmDisplacedNormalAccurate(rvec3 su, rvec3 sv, rvec3 N, rvec3 Nu, rvec3 Nv, rvec3 d1,
                                         DM_OUT(rvec3) fu, DM_OUT(rvec3) fv) {
    fu = (su + Nu * d1.x) + N * d1.y;
    fv = (sv + Nv * d1.x) + N * d1.z;
    return dmSafeNormalize(cross(fu, fv), N);
}

// Sine of the angle between the approximate displaced normal (frame a_u, a_v) and the one
// with the Weingarten term D (N_u, N_v) added, i.e. the accurate normal for that D: how far
// the approximation is off at one point. 1 where either frame degenerates (no bound).
DM_TFUNC real dmWeingartenAngleSine(rvec3 au, rvec3 av, rvec3 Nu, rvec3 Nv, real D) {
    rvec3 n1 = cross(au, av);
    rvec3 n2 = cross(au + Nu * D, av + Nv * D);
    real den = sqrt(dmDot3(n1, n1)) * sqrt(dmDot3(n2, n2));
    rvec3 c = cross(n1, n2);
    real num = sqrt(dmDot3(c, c));
    if (num < den) {
        return num / den;
    }
    return real(1);
}

// §5.4: near an extraordinary vertex s_u and s_v are not consistently defined, so the normal
// blends bilinearly towards the limit normal there. evNormal is the sum over the patch's
// extraordinary corners of (bilinear weight x limit normal), evWeight the sum of those
// weights (1 at an extraordinary vertex, 0 at the other corners).
DM_TFUNC rvec3 dmBlendLimitNormal(rvec3 n, rvec3 evNormal, real evWeight) {
    return dmSafeNormalize(evNormal + n * (real(1) - evWeight), n);
}

// §5.4 without the seam: across an end-cap patch at an extraordinary vertex the normal is
// interpolated bilinearly from normals at the patch's corners (n0 at local (0,0), n1 (1,0),
// n2 (1,1), n3 (0,1)), st the local coordinates, evCorner (0..3) the corner at the vertex. The
// caller passes the limit normal at the extraordinary corner and the displaced normal at the
// others. Two faces of an edge out of the vertex share that edge's two corners, and on the edge
// only their weights are non-zero, so both sides compute the same normal there
// (dmBlendLimitNormal instead keeps each face's own derivatives, which Gregory end caps do not
// make agree across the edge). Towards the patch's two outer edges the result blends back to
// `own`, the patch's own displaced normal, with the weight w = a b / (a b + (1-a)(1-b)), (a, b)
// the local coordinates seen from the extraordinary corner: 0 on the edges out of the vertex,
// 1 on the outer edges, so that the normal also meets the regular patches around the end cap
// (0 where both hold, at the two corners on the edges out of the vertex).
DM_TFUNC rvec3 dmEndCapNormal(rvec3 n0, rvec3 n1, rvec3 n2, rvec3 n3, rvec2 st, rvec3 own, int evCorner) {
    real s = st.x;
    real t = st.y;
    rvec3 a = n0 * ((real(1) - s) * (real(1) - t)) + n1 * (s * (real(1) - t));
    rvec3 b = n2 * (s * t) + n3 * ((real(1) - s) * t);
    rvec3 n = dmSafeNormalize(a + b, n0);
    real x = s;
    real y = t;
    if (evCorner == 1 || evCorner == 2) {
        x = real(1) - s;
    }
    if (evCorner >= 2) {
        y = real(1) - t;
    }
    real inner = x * y;
    real outer = (real(1) - x) * (real(1) - y);
    real w = real(0);
    if (inner + outer > real(0)) {
        w = inner / (inner + outer);
    }
    return dmSafeNormalize(n * (real(1) - w) + own * w, n);
}
// dispmap:glsl-end
} // namespace dispmap::kern
#include "dispmap/kernels/prelude_end.h"
