#pragma once
// The Catmull-Clark base surface on the GPU: OpenSubdiv Far::PatchTable patches evaluated
// from their control points (docs/design.md, Conventions, "The base surface on the GPU").
// Source: regular patches are the bicubic uniform B-spline limit of Catmull-Clark (Stam 1998)
// with OpenSubdiv's boundary rule; irregular ones are the end caps Far builds, either
// Gregory-basis patches (Loop, Schaefer, Ni & Castaño 2009, "Approximating subdivision
// surfaces with Gregory patches for hardware tessellation") or B-spline-basis ones; §5.4 of
// Nießner & Loop 2013 for the corner blend data.
//
// Conventions, as OpenSubdiv 3.5 (far/patchParam.h, far/patchBasis.cpp, osd/patchBasisCommon.h):
//  * a Far::PatchParam is read as uvec2(field0, field1): field0 bits 0..27 the Ptex face id,
//    28..31 the transition mask; field1 bits 0..3 the depth, bit 4 NonQuadRoot, bit 5
//    regular, bits 7..11 the boundary mask (bit 11 only for triangles), bits 12..21 V, 22..31 U;
//  * a patch covers the square [U, U+1] x [V, V+1] * 2^-L of its Ptex face, L = depth -
//    NonQuadRoot (a sub-face of an N-gon is already a whole Ptex face at depth 1);
//  * 16-point patches (regular, and B-spline end caps): control point 4i + j is column j along
//    u, row i along v. Boundary mask bit 0: the edge v = 0, bit 1: u = 1, bit 2: v = 1, bit 3:
//    u = 0; along a boundary edge the outer row is a phantom row P0 = 2 P1 - P2, folded into the
//    weights (w1 += 2 w0, w2 -= w0, w0 = 0);
//  * 20-point Gregory-basis patches: per corner k (0 at (0,0), 1 at (1,0), 2 at (1,1), 3 at
//    (0,1)) five points 5k .. 5k+4: the corner P, its two edge points e+ and e- and its two
//    face points f+ and f-; the boundary points sit on the 4 x 4 Bezier net at
//      0 (0,0)  1 (1,0)  7 (2,0)  5 (3,0)  2 (0,1)  6 (3,1)  16 (0,2)  12 (3,2)
//      15 (0,3) 17 (1,3) 11 (2,3) 10 (3,3)          (column along u, row along v),
//    and each interior Bezier point is a rational blend of its two face points:
//      (1,1) = [s f0+ + t f0-]/(s+t)      points 3, 4
//      (2,1) = [t f1+ + (1-s) f1-]/(1-s+t) points 8, 9
//      (2,2) = [(1-s) f2+ + (1-t) f2-]/(2-s-t) points 13, 14
//      (1,2) = [(1-t) f3+ + s f3-]/(1+s-t) points 18, 19
//    the minus weight being 1 minus the plus one (Far's rule: the pair sums to 1 exactly),
//    and the plus weight 0 where its denominator is 0 (at the corner itself, where the
//    Bezier weight vanishes but its mixed derivative does not: s_uv there reads f-).
//    Derivatives are OpenSubdiv's default "pseudo-derivatives": those of the Bezier patch with
//    the blended interior points held fixed (Far's EvaluateBasis built without
//    OPENSUBDIV_GREGORY_EVAL_TRUE_DERIVATIVES, as Debian's libosd is), so that the CPU
//    reference and these kernels return the same numbers;
//  * derivatives are with respect to the Ptex face's (u, v): local ones times 2^L (2^2L for
//    second). Far's EvaluateBasis scales by 2^depth instead, which is 2x too much for
//    NonQuadRoot patches (BaseSurface halves afterwards); these kernels use 2^L directly.
#include "dispmap/kernels/prelude.h"

namespace dispmap::kern {
// dispmap:glsl-begin double
// Far::PatchParam::GetDepth(): the refinement level the patch was taken at.
DM_FUNC int dmPatchDepth(uvec2 param) {
    return int(param.y & 0xFu);
}

// Far::PatchParam::NonQuadRoot(): the patch lies in a sub-face of a non-quad base face.
DM_FUNC bool dmPatchNonQuadRoot(uvec2 param) {
    return ((param.y >> 4u) & 1u) != 0u;
}

// Far::PatchParam::IsRegular(): a regular B-spline patch (false for end caps).
DM_FUNC bool dmPatchRegular(uvec2 param) {
    return ((param.y >> 5u) & 1u) != 0u;
}

// Far::PatchParam::GetBoundary() for quads: bit 0 the edge v = 0, bit 1 u = 1, bit 2 v = 1,
// bit 3 u = 0.
DM_FUNC int dmPatchBoundary(uvec2 param) {
    return int((param.y >> 7u) & 0xFu);
}

// Far::PatchParam::GetU(), GetV(): the patch's square in units of 2^-L of its Ptex face.
DM_FUNC ivec2 dmPatchOffset(uvec2 param) {
    return ivec2(int((param.y >> 22u) & 0x3FFu), int((param.y >> 12u) & 0x3FFu));
}

// Far::PatchParam::GetFaceId(): the Ptex face the patch lies in.
DM_FUNC int dmPatchFaceId(uvec2 param) {
    return int(param.x & 0xFFFFFFFu);
}

// L = depth - NonQuadRoot: the patch covers a 2^-L x 2^-L square of its Ptex face
// (Far::PatchParam::GetParamFraction() = 2^-L); derivatives carry the factor 2^L.
DM_FUNC int dmPatchDomainLevel(uvec2 param) {
    int nonQuad = 0;
    if (dmPatchNonQuadRoot(param)) {
        nonQuad = 1;
    }
    return dmPatchDepth(param) - nonQuad;
}

// Far::PatchParam::Normalize(): the patch's local parameter of a point of its Ptex face,
// faceUV * 2^L - (U, V). Exact in floating point (a power-of-two scale and the subtraction of
// an integer from a number within 1 of it).
DM_TFUNC rvec2 dmPatchLocal(uvec2 param, rvec2 faceUV) {
    real scale = real(1 << dmPatchDomainLevel(param));
    return faceUV * scale - rvec2(dmPatchOffset(param));
}

// One step down the per-face quadtree of Far::PatchMap: returns the quadrant holding uv (bit 0:
// u >= 1/2, bit 1: v >= 1/2, so u = 1 and v = 1 belong to the upper halves) and maps uv to
// that quadrant's [0, 1]^2 (uv * 2 - quadrant offset, exact in floating point).
DM_TFUNC int dmQuadTreeStep(DM_INOUT(rvec2) uv) {
    int q = 0;
    if (uv.x >= real(0.5)) {
        q = 1;
    }
    if (uv.y >= real(0.5)) {
        q = q + 2;
    }
    uv = uv * real(2) - rvec2(real(q & 1), real(q >> 1));
    return q;
}

// The four cubic uniform B-spline basis functions non-zero on one knot interval, t in [0, 1]:
// ((1-t)^3, 3t^3 - 6t^2 + 4, 3(1-t)^3 - 6(1-t)^2 + 4, t^3) / 6, mirror-symmetric in t <-> 1-t.
DM_TFUNC rvec4 dmBSpline3(real t) {
    real s = real(1) - t;
    // 1/6 as a constant (folded at compile time on both sides): no division at run time.
    return rvec4(s * s * s, (real(3) * t - real(6)) * t * t + real(4), (real(3) * s - real(6)) * s * s + real(4), t * t * t) *
           (real(1) / real(6));
}

// First derivatives d/dt of dmBSpline3: (-(1-t)^2, t(3t - 4), -(1-t)(3(1-t) - 4), t^2) / 2.
DM_TFUNC rvec4 dmBSpline3D1(real t) {
    real s = real(1) - t;
    return rvec4(-(s * s), t * (real(3) * t - real(4)), -(s * (real(3) * s - real(4))), t * t) * real(0.5);
}

// Second derivatives d2/dt2 of dmBSpline3: (1-t, 3t - 2, 3(1-t) - 2, t).
DM_TFUNC rvec4 dmBSpline3D2(real t) {
    real s = real(1) - t;
    return rvec4(s, real(3) * t - real(2), real(3) * s - real(2), t);
}

// The cubic Bernstein (Bezier) basis: ((1-t)^3, 3(1-t)^2 t, 3(1-t) t^2, t^3).
DM_TFUNC rvec4 dmBezier3(real t) {
    real s = real(1) - t;
    return rvec4(s * s * s, real(3) * s * s * t, real(3) * s * t * t, t * t * t);
}

// First derivatives of dmBezier3: (-3(1-t)^2, 3(1-t)(1-3t), 3t(2-3t), 3t^2), written with
// s = 1 - t as (-3s^2, 3s(s - 2t), 3t(2s - t), 3t^2).
DM_TFUNC rvec4 dmBezier3D1(real t) {
    real s = real(1) - t;
    return rvec4(-(real(3) * s * s), real(3) * s * (s - real(2) * t), real(3) * t * (real(2) * s - t), real(3) * t * t);
}

// Second derivatives of dmBezier3: 6 (1-t, 3t - 2, 1 - 3t, t), written with s = 1 - t as
// 6 (s, t - 2s, s - 2t, t).
DM_TFUNC rvec4 dmBezier3D2(real t) {
    real s = real(1) - t;
    return rvec4(s, t - real(2) * s, s - real(2) * t, t) * real(6);
}

// OpenSubdiv's boundary rule on one direction of a B-spline patch: the outer control row on a
// boundary edge is the phantom 2 P1 - P2 (P0 at the `low` end, P3 at the `high` end), so its
// weight moves onto the two rows inside.
DM_TFUNC rvec4 dmFoldBoundary(rvec4 w, bool low, bool high) {
    rvec4 r = w;
    if (low) {
        r.y = r.y + real(2) * r.x;
        r.z = r.z - r.x;
        r.x = real(0);
    }
    if (high) {
        r.z = r.z + real(2) * r.w;
        r.y = r.y - r.w;
        r.w = real(0);
    }
    return r;
}

// Tensor-product weights of a 16-point patch: w[4i + j] = a[j] * b[i] * scale, a along u
// (column j), b along v (row i). Entries 16..19 are set to 0.
DM_TFUNC void dmTensor16(rvec4 a, rvec4 b, real scale, DM_OUT_ARRAY(real) w[20]) {
    for (int i = 0; i < 4; ++i) {
        for (int j = 0; j < 4; ++j) {
            w[4 * i + j] = a[j] * b[i] * scale;
        }
    }
    for (int k = 16; k < 20; ++k) {
        w[k] = real(0);
    }
}

// The rational blend weights of the Gregory patch's face points at local (s, t) (the layout at
// the top of this file): gPlus for f0+, f1+, f2+, f3+ (points 3, 8, 13, 18), gMinus for f0-,
// f1-, f2-, f3- (points 4, 9, 14, 19). gMinus = 1 - gPlus, so each pair sums to 1 also at its
// own corner, where the denominator vanishes and gPlus is taken as 0 (Far's convention).
DM_TFUNC void dmGregoryBlend(rvec2 st, DM_OUT(rvec4) gPlus, DM_OUT(rvec4) gMinus) {
    real s = st.x;
    real t = st.y;
    real sc = real(1) - s;
    real tc = real(1) - t;
    rvec4 d = rvec4(s + t, sc + t, sc + tc, s + tc);
    for (int k = 0; k < 4; ++k) {
        if (d[k] <= real(0)) {
            d[k] = real(1);
        } else {
            d[k] = real(1) / d[k];
        }
    }
    gPlus = rvec4(s * d.x, t * d.y, sc * d.z, tc * d.w);
    gMinus = rvec4(real(1)) - gPlus;
}

// Weights of a 20-point Gregory-basis patch from a u-basis a and a v-basis b on the 4 x 4
// Bezier net (values or derivatives of dmBezier3), times scale: a boundary point gets
// a[col] * b[row] * scale, an interior face point a[col] * b[row] * g * scale with its blend
// weight g (the pseudo-derivative convention when a or b are derivatives).
DM_TFUNC void dmGregoryTensor20(rvec4 a, rvec4 b, rvec4 gPlus, rvec4 gMinus, real scale, DM_OUT_ARRAY(real) w[20]) {
    w[0] = a.x * b.x * scale;
    w[1] = a.y * b.x * scale;
    w[2] = a.x * b.y * scale;
    w[3] = a.y * b.y * gPlus.x * scale;
    w[4] = a.y * b.y * gMinus.x * scale;
    w[5] = a.w * b.x * scale;
    w[6] = a.w * b.y * scale;
    w[7] = a.z * b.x * scale;
    w[8] = a.z * b.y * gPlus.y * scale;
    w[9] = a.z * b.y * gMinus.y * scale;
    w[10] = a.w * b.w * scale;
    w[11] = a.z * b.w * scale;
    w[12] = a.w * b.z * scale;
    w[13] = a.z * b.z * gPlus.z * scale;
    w[14] = a.z * b.z * gMinus.z * scale;
    w[15] = a.x * b.w * scale;
    w[16] = a.x * b.z * scale;
    w[17] = a.y * b.w * scale;
    w[18] = a.y * b.z * gPlus.w * scale;
    w[19] = a.y * b.z * gMinus.w * scale;
}

// Weights of the control points of a Far patch and their first derivatives with respect to the
// Ptex face's (u, v), at faceUV (a point of the patch's square; see dmPatchLocal). cvCount is
// the patch's number of control points: 20 for Gregory-basis end caps, 16 for regular patches
// and B-spline end caps (boundary mask applied; entries 16..19 set to 0). sum_i w[i] P_i is
// the surface point, sum_i wu[i] P_i and sum_i wv[i] P_i its derivatives: the numbers of
// Far::PatchTable::EvaluateBasis, with the 2^L derivative scale (see the top of this file).
DM_TFUNC void dmPatchBasis1(uvec2 param, int cvCount, rvec2 faceUV, DM_OUT_ARRAY(real) w[20], DM_OUT_ARRAY(real) wu[20],
                            DM_OUT_ARRAY(real) wv[20]) {
    rvec2 st = dmPatchLocal(param, faceUV);
    real d1 = real(1 << dmPatchDomainLevel(param));
    if (cvCount == 20) {
        rvec4 gPlus;
        rvec4 gMinus;
        dmGregoryBlend(st, gPlus, gMinus);
        rvec4 bs = dmBezier3(st.x);
        rvec4 bt = dmBezier3(st.y);
        dmGregoryTensor20(bs, bt, gPlus, gMinus, real(1), w);
        dmGregoryTensor20(dmBezier3D1(st.x), bt, gPlus, gMinus, d1, wu);
        dmGregoryTensor20(bs, dmBezier3D1(st.y), gPlus, gMinus, d1, wv);
    } else {
        int b = dmPatchBoundary(param);
        bool u0 = (b & 8) != 0;
        bool u1 = (b & 2) != 0;
        bool v0 = (b & 1) != 0;
        bool v1 = (b & 4) != 0;
        rvec4 bs = dmFoldBoundary(dmBSpline3(st.x), u0, u1);
        rvec4 bt = dmFoldBoundary(dmBSpline3(st.y), v0, v1);
        dmTensor16(bs, bt, real(1), w);
        dmTensor16(dmFoldBoundary(dmBSpline3D1(st.x), u0, u1), bt, d1, wu);
        dmTensor16(bs, dmFoldBoundary(dmBSpline3D1(st.y), v0, v1), d1, wv);
    }
}

// dmPatchBasis1 plus the second derivatives wuu, wuv, wvv with respect to the Ptex face's
// (u, v) (factor 2^2L).
DM_TFUNC void dmPatchBasis2(uvec2 param, int cvCount, rvec2 faceUV, DM_OUT_ARRAY(real) w[20], DM_OUT_ARRAY(real) wu[20],
                            DM_OUT_ARRAY(real) wv[20], DM_OUT_ARRAY(real) wuu[20], DM_OUT_ARRAY(real) wuv[20],
                            DM_OUT_ARRAY(real) wvv[20]) {
    rvec2 st = dmPatchLocal(param, faceUV);
    real d1 = real(1 << dmPatchDomainLevel(param));
    real d2 = d1 * d1;
    if (cvCount == 20) {
        rvec4 gPlus;
        rvec4 gMinus;
        dmGregoryBlend(st, gPlus, gMinus);
        rvec4 bs = dmBezier3(st.x);
        rvec4 bt = dmBezier3(st.y);
        rvec4 bds = dmBezier3D1(st.x);
        rvec4 bdt = dmBezier3D1(st.y);
        dmGregoryTensor20(bs, bt, gPlus, gMinus, real(1), w);
        dmGregoryTensor20(bds, bt, gPlus, gMinus, d1, wu);
        dmGregoryTensor20(bs, bdt, gPlus, gMinus, d1, wv);
        dmGregoryTensor20(dmBezier3D2(st.x), bt, gPlus, gMinus, d2, wuu);
        dmGregoryTensor20(bds, bdt, gPlus, gMinus, d2, wuv);
        dmGregoryTensor20(bs, dmBezier3D2(st.y), gPlus, gMinus, d2, wvv);
    } else {
        int b = dmPatchBoundary(param);
        bool u0 = (b & 8) != 0;
        bool u1 = (b & 2) != 0;
        bool v0 = (b & 1) != 0;
        bool v1 = (b & 4) != 0;
        rvec4 bs = dmFoldBoundary(dmBSpline3(st.x), u0, u1);
        rvec4 bt = dmFoldBoundary(dmBSpline3(st.y), v0, v1);
        rvec4 bds = dmFoldBoundary(dmBSpline3D1(st.x), u0, u1);
        rvec4 bdt = dmFoldBoundary(dmBSpline3D1(st.y), v0, v1);
        dmTensor16(bs, bt, real(1), w);
        dmTensor16(bds, bt, d1, wu);
        dmTensor16(bs, bdt, d1, wv);
        dmTensor16(dmFoldBoundary(dmBSpline3D2(st.x), u0, u1), bt, d2, wuu);
        dmTensor16(bds, bdt, d2, wuv);
        dmTensor16(bs, dmFoldBoundary(dmBSpline3D2(st.y), v0, v1), d2, wvv);
    }
}

// §5.4 blend data of an end-cap patch: for each Ptex face corner c (0 at (0,0), 1 at (1,0),
// 2 at (1,1), 3 at (0,1)) that the patch's square touches, the bilinear weight of that corner
// in the patch's local coordinates at faceUV ((1-s)(1-t), s(1-t), st, (1-s)t); 0 for corners
// it does not touch, and all 0 for regular patches. The caller keeps the extraordinary
// corners and blends their limit normals with these weights (dmBlendLimitNormal).
DM_TFUNC rvec4 dmEndCapCornerWeights(uvec2 param, rvec2 faceUV) {
    rvec4 r = rvec4(real(0));
    if (!dmPatchRegular(param)) {
        ivec2 o = dmPatchOffset(param);
        int last = (1 << dmPatchDomainLevel(param)) - 1;
        rvec2 st = dmPatchLocal(param, faceUV);
        real sc = real(1) - st.x;
        real tc = real(1) - st.y;
        bool u0 = o.x == 0;
        bool v0 = o.y == 0;
        bool u1 = o.x == last;
        bool v1 = o.y == last;
        if (u0 && v0) {
            r.x = sc * tc;
        }
        if (u1 && v0) {
            r.y = st.x * tc;
        }
        if (u1 && v1) {
            r.z = st.x * st.y;
        }
        if (u0 && v1) {
            r.w = sc * st.y;
        }
    }
    return r;
}
// dispmap:glsl-end
} // namespace dispmap::kern
#include "dispmap/kernels/prelude_end.h"
