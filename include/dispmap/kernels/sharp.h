#pragma once
// Watertight displacement at infinitely sharp features (docs/design.md, "Sharp creases and
// corners").
//
// f = s + N D moves the two faces of an edge apart wherever their normals differ there: along
// an infinitely sharp crease each face has its own one-sided normal, and so has every face at
// an infinitely sharp corner. The rule: D fades to 0 towards such features,
//     f = s + N (w D),   w = smoothstep(d / band),
// where d is the distance, in units of a base face edge, from (u, v) to the nearest sharp
// feature of the face: a sharp edge of the face (the perpendicular distance), or a "touched"
// corner (the Euclidean distance), a base vertex that lies on an interior sharp edge or is an
// infinitely sharp corner shared by several faces. On the feature w = 0, so f = s there from
// every side, whatever the normals. Along any other edge w depends only on the edge parameter
// and the flags of the edge's two end vertices (which both faces of the edge share, and band
// <= 1/2 keeps the two ends' ramps apart), so f stays single-valued there too; and the
// derivative of w across such an edge is 0 on both sides, so the displaced normal stays
// continuous. smoothstep's zero slope at 0 makes the displaced normal equal the base normal on
// the feature itself: the one-sided normal, as a sharp crease should shade.
//
// The mask (BaseSurface::sharpMask): bit i (0..3) Ptex edge i is sharp (edge i runs from corner
// i to corner i + 1: v = 0, u = 1, v = 1, u = 0), bit 4 + c corner c is touched (0 at (0,0),
// 1 at (1,0), 2 at (1,1), 3 at (0,1)). subFace is 1 for a sub-face of an N-gon, whose (u, v)
// spans half a base edge: distances are halved so that a quad and the sub-faces across one of
// its edges measure the same distance. Around a touched corner D vanishes on a disc of the
// end caps' size first (capRadius, see below), then fades in.
#include "dispmap/kernels/prelude.h"

namespace dispmap::kern {
// dispmap:glsl-begin double
// (w D, (w D)_u, (w D)_v) from d1 = (D, D_u, D_v) at face (u, v); d1 unchanged where mask is 0,
// band <= 0 or (u, v) is at least `band` from every sharp feature. Distances are in base-face
// edge lengths; a touched corner's distance is measured from a disc of radius capRadius around
// it (the caller passes the end caps' diagonal, sqrt(2) 2^-isolation: Far's end caps at
// extraordinary vertices on creases are not G1 across their smooth edges, so D must vanish on
// all of them, not only at the vertex).
DM_TFUNC rvec3 dmSharpFeather(rvec2 uv, int mask, int subFace, real band, real capRadius, rvec3 d1) {
    if (mask == 0 || !(band > real(0))) {
        return d1;
    }
    real scale = real(1);
    if (subFace != 0) {
        scale = real(0.5);
    }
    // Nearest feature: distance (base-face units) and its gradient in (u, v).
    real d = real(2);
    rvec2 g = rvec2(real(0));
    if ((mask & 1) != 0 && uv.y * scale < d) {
        d = uv.y * scale;
        g = rvec2(real(0), scale);
    }
    if ((mask & 2) != 0 && (real(1) - uv.x) * scale < d) {
        d = (real(1) - uv.x) * scale;
        g = rvec2(-scale, real(0));
    }
    if ((mask & 4) != 0 && (real(1) - uv.y) * scale < d) {
        d = (real(1) - uv.y) * scale;
        g = rvec2(real(0), -scale);
    }
    if ((mask & 8) != 0 && uv.x * scale < d) {
        d = uv.x * scale;
        g = rvec2(scale, real(0));
    }
    for (int c = 0; c < 4; ++c) {
        if ((mask & (16 << c)) != 0) {
            rvec2 corner = rvec2(real(0));
            if (c == 1 || c == 2) {
                corner.x = real(1);
            }
            if (c >= 2) {
                corner.y = real(1);
            }
            rvec2 r = uv - corner;
            real l = sqrt(r.x * r.x + r.y * r.y);
            real dc = max(l * scale - capRadius, real(0));
            if (dc < d) {
                d = dc;
                g = rvec2(real(0));
                if (dc > real(0)) {
                    g = r * (scale / l);
                }
            }
        }
    }
    real x = d / band;
    if (x >= real(1)) {
        return d1;
    }
    real w = x * x * (real(3) - real(2) * x);
    real dw = real(6) * x * (real(1) - x) / band;
    return rvec3(w * d1.x, w * d1.y + dw * g.x * d1.x, w * d1.z + dw * g.y * d1.x);
}
// dispmap:glsl-end
} // namespace dispmap::kern
#include "dispmap/kernels/prelude_end.h"
