#pragma once
// Per-pixel mesostructure ray marching: the step kernels of every marcher (Donnelly, GPU Gems 2
// ch. 8: sphere tracing a distance map; Mehra & Kumar 2012: directional distance maps (DDM),
// quadrics, voxel-wall stepping; Policarpo 2005 relief mapping; Tatarchuk 2006 parallax
// occlusion mapping) and the exact ray / bilinear-height-cell root used as the reference.
//
// Voxel space (all kernels): a volume of W x H x L cubic voxels, voxel (i, j, k) the box
// [i, i+1] x [j, j+1] x [k, k+1]; x and y repeat with periods W and H (a tiling texture),
// z runs from 0 (the bottom) to L (the base surface, where rays enter). The height field has
// one height per texel grid point (i, j), in voxels, in [0, L]; the surface is its bilinear
// interpolant H(x, y), solid below. Column (i, j) is the cell [i, i+1] x [j, j+1]: there H is
// one bilinear patch with corners h = (h00, h10, h11, h01) (dmBilerp's order), so every
// method and the reference see the same surface. A tangent-space ray is taken into voxel
// space by dmTangentToVoxel (Donnelly's normalisation factor).
//
// The marchers' loops live with the memory they read (include/dispmap/meso/march.h on the
// CPU, shaders/meso/march.glsl on the GPU): each loop iteration fetches what the kernel of
// its method needs and calls it, so every decision (step length, cone, stop, root) is made
// here, once. `dispmap parity` and tests/gpu check that both sides give the same hits and
// iteration counts bit for bit.
#include "dispmap/kernels/sum.h"
#include "dispmap/kernels/tile.h" // dmBilerp
#include "dispmap/kernels/prelude.h"

namespace dispmap::kern {
using glm::floatBitsToUint;
using glm::ivec3;
using glm::uintBitsToFloat;
// dispmap:glsl-begin double
// --- Roots --------------------------------------------------------------------------------
// Real roots t0 <= t1 of a t^2 + b t + c (returns how many: 0, 1 when a = 0 and b != 0, else
// 2). Stable form (pbrt-v4's Quadratic): q = -(b + sign(b) sqrt(disc)) / 2, t = q / a and
// c / q, so neither root is formed by cancelling b against sqrt(disc). Only a == 0 branches:
// as a -> 0, c / q tends to -c / b by itself and q / a to +-Inf (no root). A discriminant in
// [-tol (b^2 + |4ac|), 0) is rounding of a tangent case and counts as a double root (tol: a
// few ULP of the precision, chosen by the caller).
DM_TFUNC int dmQuadraticRoots(real a, real b, real c, real tol, DM_OUT(real) t0, DM_OUT(real) t1) {
    t0 = real(0);
    t1 = real(0);
    if (a == real(0)) {
        if (b == real(0)) {
            return 0;
        }
        t0 = -c / b;
        t1 = t0;
        return 1;
    }
    real b2 = b * b;
    real ac4 = (real(4) * a) * c;
    real disc = b2 - ac4;
    if (disc < real(0)) {
        if (disc < -tol * (b2 + abs(ac4))) {
            return 0;
        }
        disc = real(0);
    }
    real sq = sqrt(disc);
    real q = real(-0.5) * (b < real(0) ? b - sq : b + sq);
    if (q == real(0)) {
        return 2; // b = 0 and disc = 0: both roots 0
    }
    real r0 = q / a;
    real r1 = c / q;
    t0 = min(r0, r1);
    t1 = max(r0, r1);
    return 2;
}

// The smallest root of a s^2 + b s + c in [lo, hi] (false when there is none).
DM_TFUNC bool dmSmallestRootIn(real a, real b, real c, real lo, real hi, real tol, DM_OUT(real) s) {
    real t0;
    real t1;
    int n = dmQuadraticRoots(a, b, c, tol, t0, t1);
    s = hi;
    if (n == 0) {
        return false;
    }
    if (t0 >= lo && t0 <= hi) {
        s = t0;
        return true;
    }
    if (t1 >= lo && t1 <= hi) {
        s = t1;
        return true;
    }
    return false;
}

// Where f, with f(0) = f0 > 0 and f(len) = f1, has the root a solver missed to rounding: the
// secant of the two ends, clamped to [0, len]. The callers use it only when f1 <= 0, so a
// sign change proves a root in [0, len]: the root is never lost.
DM_TFUNC real dmSecantRoot(real f0, real f1, real len) {
    return clamp(len * (f0 / (f0 - f1)), real(0), len);
}

// --- The exact reference: a ray against one bilinear height cell ---------------------------
// The ray o + s d, s in [0, len], with o in the column's local frame (x - i, y - j, z) and
// h = (h00, h10, h11, h01) its corner heights. Solid is z <= H. Writes the first s where the
// ray meets the patch (0 when o is already at or below it) and returns true, or false when it
// stays above. f(s) = o.z + s d.z - H(o + s d) is quadratic in s: with k = h00 - h10 + h11 -
// h01, bx = h10 - h00, by = h01 - h00, f = A s^2 + B s + f(0), A = -k dx dy,
// B = dz - bx dx - by dy - k (ox dy + oy dx).
DM_TFUNC bool dmRayHeightCell(rvec3 o, rvec3 d, rvec4 h, real len, real tol, DM_OUT(real) s) {
    real k = (h.x - h.y) + (h.z - h.w);
    real bx = h.y - h.x;
    real by = h.w - h.x;
    real f0 = o.z - dmBilerp(h, rvec2(o.x, o.y));
    s = real(0);
    if (f0 <= real(0)) {
        return true;
    }
    real A = -(k * d.x) * d.y;
    real B = ((d.z - bx * d.x) - by * d.y) - k * (o.x * d.y + o.y * d.x);
    if (dmSmallestRootIn(A, B, f0, real(0), len, tol, s)) {
        return true;
    }
    rvec3 e = o + d * len;
    real f1 = e.z - dmBilerp(h, rvec2(e.x, e.y));
    if (f1 <= real(0)) {
        s = dmSecantRoot(f0, f1, len);
        return true;
    }
    return false;
}

// --- Quadrics (Mehra & Kumar Eq. 1) --------------------------------------------------------
// Q(p) = A x^2 + B y^2 + C z^2 + D xy + E yz + F zx + G x + H y + I z + J with
// qa = (A, B, C, D), qb = (E, F, G, H), qc = (I, J, ., .) in a frame local to the voxel;
// Q > 0 is inside the solid. Fixed-order sums, as everywhere a kernel promises parity.
DM_TFUNC real dmQuadricValue(rvec4 qa, rvec4 qb, rvec4 qc, rvec3 p) {
    real quad = ((qa.x * p.x) * p.x + (qa.y * p.y) * p.y) + (qa.z * p.z) * p.z;
    real mixed = ((qa.w * p.x) * p.y + (qb.x * p.y) * p.z) + (qb.y * p.z) * p.x;
    real lin = ((qb.z * p.x + qb.w * p.y) + qc.x * p.z) + qc.y;
    return (quad + mixed) + lin;
}

// Q(o + s d) = a2 s^2 + a1 s + a0: returns (a2, a1, a0).
DM_TFUNC rvec3 dmRayQuadricPolynomial(rvec4 qa, rvec4 qb, rvec4 qc, rvec3 o, rvec3 d) {
    real a2 = (((qa.x * d.x) * d.x + (qa.y * d.y) * d.y) + (qa.z * d.z) * d.z) +
              (((qa.w * d.x) * d.y + (qb.x * d.y) * d.z) + (qb.y * d.z) * d.x);
    real sq = real(2) * (((qa.x * o.x) * d.x + (qa.y * o.y) * d.y) + (qa.z * o.z) * d.z);
    real mixed = (qa.w * (o.x * d.y + o.y * d.x) + qb.x * (o.y * d.z + o.z * d.y)) + qb.y * (o.z * d.x + o.x * d.z);
    real lin = (qb.z * d.x + qb.w * d.y) + qc.x * d.z;
    return rvec3(a2, (sq + mixed) + lin, dmQuadricValue(qa, qb, qc, o));
}

// Algorithm 3.2: the first s in [0, len] where o + s d meets the quadric (0 when o is inside),
// false when the ray stays outside within len. A sign change the root solver missed to
// rounding is still a hit (dmSecantRoot).
DM_TFUNC bool dmRayQuadric(rvec4 qa, rvec4 qb, rvec4 qc, rvec3 o, rvec3 d, real len, real tol, DM_OUT(real) s) {
    rvec3 p = dmRayQuadricPolynomial(qa, qb, qc, o, d);
    s = real(0);
    if (p.z >= real(0)) {
        return true;
    }
    // Q < 0 outside: roots of -Q are those of Q.
    if (dmSmallestRootIn(p.x, p.y, p.z, real(0), len, tol, s)) {
        return true;
    }
    real f1 = dmQuadricValue(qa, qb, qc, o + d * len);
    if (f1 >= real(0)) {
        s = dmSecantRoot(-p.z, -f1, len);
        return true;
    }
    return false;
}

// The quadric a voxel of layer k uses from its column's record (qa, qb, qc with qc.z, qc.w =
// the lowest and highest corner height): the column's patch where [k, k + 1] meets
// [qc.z, qc.w]; Q = +1 (all solid: a ray there is inside) when k + 1 <= qc.z; Q = -1 (no
// surface) when k >= qc.w. Writes the voxel's three records.
DM_TFUNC void dmVoxelQuadric(rvec4 qa, rvec4 qb, rvec4 qc, int k, DM_OUT(rvec4) va, DM_OUT(rvec4) vb, DM_OUT(rvec4) vc) {
    va = qa;
    vb = qb;
    vc = qc;
    real lo = real(k);
    if (lo + real(1) <= qc.z || lo >= qc.w) {
        va = rvec4(real(0));
        vb = rvec4(real(0));
        vc = rvec4(real(0), lo + real(1) <= qc.z ? real(1) : real(-1), real(0), real(0));
    }
}

// The unit geometric normal of a solid's triangle (edges e1, e2), turned to the side the ray d
// came from (an open mesh is a two-sided sheet); the shading normal n is turned to that side
// with it. The shadow ray leaves along the geometric normal (the interpolated one may point
// into a neighbouring face at a silhouette).
DM_TFUNC rvec3 dmSolidFacing(rvec3 e1, rvec3 e2, rvec3 d, DM_INOUT(rvec3) n) {
    rvec3 g = dmCross3(e1, e2);
    g = g * (real(1) / sqrt(dmDot3(g, g)));
    if (dmDot3(g, d) > real(0)) {
        g = -g;
    }
    if (dmDot3(n, g) < real(0)) {
        n = -n;
    }
    return g;
}

// floor(i / n) for n > 0 and any i (C++ and GLSL round a negative quotient towards 0).
DM_FUNC int dmFloorDiv(int i, int n) {
    return i >= 0 ? i / n : -((-1 - i) / n) - 1;
}

// --- Triangles (non-height-field detail, meso/solid.h) ---------------------------------------
// Moller & Trumbore (1997): the crossing of o + t d with the triangle a, a + e1, a + e2 (either
// face) for t in [t0, tBest]. On a hit tBest becomes its t and uv its barycentric (u, v) (the
// point a + u e1 + v e2) and it returns true. A ray (nearly) parallel to the plane, |det| <=
// 1e-20 (det = e1 . (d x e2), |d| = 1: twice the area of the triangle seen along d), misses:
// float and double draw the same line, far below any triangle a voxelised mesh holds.
DM_TFUNC bool dmRayTriangle(rvec3 o, rvec3 d, rvec3 a, rvec3 e1, rvec3 e2, real t0, DM_INOUT(real) tBest, DM_INOUT(rvec2) uv) {
    rvec3 p = dmCross3(d, e2);
    real det = dmDot3(e1, p);
    if (!(abs(det) > real(1e-20))) {
        return false;
    }
    rvec3 w = o - a;
    real u = dmDot3(w, p) / det;
    if (u < real(0) || u > real(1)) {
        return false;
    }
    rvec3 q = dmCross3(w, e1);
    real v = dmDot3(d, q) / det;
    if (v < real(0) || u + v > real(1)) {
        return false;
    }
    real t = dmDot3(e2, q) / det;
    if (t < t0 || t > tBest) {
        return false;
    }
    tBest = t;
    uv = rvec2(u, v);
    return true;
}

// The unit vector whose octahedral encoding is e in [-1, 1]^2 (Cigolle et al. 2014, "A survey
// of efficient representations for independent unit vectors"; packSolid encodes).
DM_TFUNC rvec3 dmOctDecode(rvec2 e) {
    rvec3 n = rvec3(e.x, e.y, (real(1) - abs(e.x)) - abs(e.y));
    if (n.z < real(0)) {
        n.x = (real(1) - abs(e.y)) * (e.x >= real(0) ? real(1) : real(-1));
        n.y = (real(1) - abs(e.x)) * (e.y >= real(0) ? real(1) : real(-1));
    }
    return n * (real(1) / sqrt(dmDot3(n, n)));
}

// GLSL's unpackSnorm2x16 (unit 32767), spelled out so that both sides round alike: the low
// and the high 16 bits as signed integers over unit, clamped to [-1, 1].
DM_TFUNC rvec2 dmUnpackSnorm2x16(uint w, real unit) {
    int lo = int(w << 16u) >> 16;
    int hi = int(w) >> 16;
    return clamp(rvec2(real(lo), real(hi)) / unit, real(-1), real(1));
}

// The shading normal at barycentric uv of a triangle whose corners' unit normals are n0, n1, n2
// (octahedral, two snorm16 a word: packSolid) mixed by uv (Phong's interpolation), unit
// length; the first corner's where they cancel.
DM_TFUNC rvec3 dmSolidCornerNormal(uint n0, uint n1, uint n2, rvec2 uv) {
    real unit = real(32767);
    rvec3 a = dmOctDecode(dmUnpackSnorm2x16(n0, unit));
    rvec3 n = (a * ((real(1) - uv.x) - uv.y) + dmOctDecode(dmUnpackSnorm2x16(n1, unit)) * uv.x) + dmOctDecode(dmUnpackSnorm2x16(n2, unit)) * uv.y;
    real l = dmDot3(n, n);
    return l > real(0) ? n * (real(1) / sqrt(l)) : a;
}

// --- Voxel traversal (Algorithm 3.3, as an exact DDA) ---------------------------------------
// The voxel containing p; a coordinate on a voxel wall belongs to the voxel the ray d enters.
DM_TFUNC ivec3 dmVoxelAt(rvec3 p, rvec3 d) {
    rvec3 f = floor(p);
    ivec3 v = ivec3(int(f.x), int(f.y), int(f.z));
    if (p.x == f.x && d.x < real(0)) {
        v.x = v.x - 1;
    }
    if (p.y == f.y && d.y < real(0)) {
        v.y = v.y - 1;
    }
    if (p.z == f.z && d.z < real(0)) {
        v.z = v.z - 1;
    }
    return v;
}

// Parameter where o + t d leaves voxel v, and the axis (0, 1, 2) of the wall it crosses.
DM_TFUNC real dmVoxelExit(rvec3 o, rvec3 d, ivec3 v, DM_OUT(int) axis) {
    real big = real(1e30);
    real tx = d.x > real(0) ? (real(v.x + 1) - o.x) / d.x : (d.x < real(0) ? (real(v.x) - o.x) / d.x : big);
    real ty = d.y > real(0) ? (real(v.y + 1) - o.y) / d.y : (d.y < real(0) ? (real(v.y) - o.y) / d.y : big);
    real tz = d.z > real(0) ? (real(v.z + 1) - o.z) / d.z : (d.z < real(0) ? (real(v.z) - o.z) / d.z : big);
    axis = 0;
    real t = tx;
    if (ty < t) {
        t = ty;
        axis = 1;
    }
    if (tz < t) {
        t = tz;
        axis = 2;
    }
    return t;
}

// The neighbour of v across the wall `axis` in the direction of d.
DM_TFUNC ivec3 dmVoxelStep(ivec3 v, rvec3 d, int axis) {
    ivec3 w = v;
    if (axis == 0) {
        w.x = w.x + (d.x > real(0) ? 1 : -1);
    } else if (axis == 1) {
        w.y = w.y + (d.y > real(0) ? 1 : -1);
    } else {
        w.z = w.z + (d.z > real(0) ? 1 : -1);
    }
    return w;
}

// Where a ray in voxel v stands against the volume's slab 0 <= z <= L: 0 inside, 1 below the
// bottom (solid: the height field fills z < 0), 2 above the top (it left: a view ray misses,
// a shadow ray reaches the light).
DM_FUNC int dmSlabStatus(ivec3 v, int L) {
    if (v.z < 0) {
        return 1;
    }
    return v.z >= L ? 2 : 0;
}

// Parameter where o + t d reaches the plane z = zPlane (d.z != 0).
DM_TFUNC real dmPlaneHit(rvec3 o, rvec3 d, real zPlane) {
    return (zPlane - o.z) / d.z;
}

// A DDM march against the slab (dmSlabStatus) in voxel v: false inside (march on); true when
// the ray has left it, with below = it went under the floor (the solid: a hit) and t moved
// onto the floor plane z = 0 when it was going down.
DM_TFUNC bool dmDdmLeftSlab(ivec3 v, int L, rvec3 o, rvec3 d, DM_INOUT(real) t, DM_OUT(bool) below) {
    int slab = dmSlabStatus(v, L);
    below = slab == 1;
    if (below && d.z < real(0)) {
        t = max(t, dmPlaneHit(o, d, real(0)));
    }
    return slab != 0;
}

// --- Direction cones (Mehra & Kumar §3.1) ---------------------------------------------------
// Cone of a voxel-space direction d among m x n cones per hemisphere: azimuth theta (from +x
// towards +y) in m equal sectors, m in {1, 2, 4, 8}; the angle below (view rays, d.z <= 0) or
// above (shadow rays, d.z > 0) the horizon in n bands, n in {1, 2} (the band boundary at 45
// degrees). Index = hemisphere * m n + band * m + sector; m == 0: one isotropic cone (0).
// Only comparisons and products: no atan, so CPU and GPU pick the same cone bit for bit; on a
// boundary either neighbour is right, because the maps are built for closed cones.
DM_TFUNC int dmConeIndex(rvec3 d, int m, int n) {
    if (m == 0) {
        return 0;
    }
    int q = d.y >= real(0) ? (d.x >= real(0) ? 0 : 1) : (d.x < real(0) ? 2 : 3);
    int sector = 0;
    if (m == 2) {
        sector = d.y >= real(0) ? 0 : 1;
    } else if (m == 4) {
        sector = q;
    } else if (m == 8) {
        bool second = (q == 0 || q == 2) ? abs(d.y) > abs(d.x) : abs(d.x) >= abs(d.y);
        sector = 2 * q + (second ? 1 : 0);
    }
    int band = 0;
    if (n == 2) {
        band = d.z * d.z > d.x * d.x + d.y * d.y ? 1 : 0;
    }
    int hemisphere = d.z > real(0) ? 1 : 0;
    return (hemisphere * n + band) * m + sector;
}

// --- Donnelly's distance map ----------------------------------------------------------------
// Tangent-space direction (x along the texture's u, y along v, z along the normal, any
// length) to a unit voxel-space direction; voxelsPerUnit = (W / texture width, H / texture
// height, L / depth) in the same world unit. Donnelly normalises in texture space and then
// scales by (depth/width, depth/height, 1); this is the same in voxel units.
DM_TFUNC rvec3 dmTangentToVoxel(rvec3 t, rvec3 voxelsPerUnit) {
    rvec3 v = rvec3(t.x * voxelsPerUnit.x, t.y * voxelsPerUnit.y, t.z * voxelsPerUnit.z);
    return v * (real(1) / sqrt(dmDot3(v, v)));
}

// Samples of Donnelly's map sit at (i, j, k + 1/2): texel grid points, layer centres. The
// sample cell of p (its lowest sample (i, j, k), unwrapped) and the trilinear fractions f;
// z is clamped into the samples' range, so L >= 2.
DM_TFUNC ivec3 dmDistanceSampleCell(rvec3 p, int L, DM_OUT(rvec3) f) {
    real zc = clamp(p.z - real(0.5), real(0), real(L - 1));
    real fx = floor(p.x);
    real fy = floor(p.y);
    int k = min(int(floor(zc)), L - 2);
    f = rvec3(p.x - fx, p.y - fy, zc - real(k));
    return ivec3(int(fx), int(fy), k);
}

// Trilinear interpolation: lo and hi the samples of layers k and k + 1 in dmBilerp's order
// ((i, j), (i+1, j), (i+1, j+1), (i, j+1)).
DM_TFUNC real dmTrilerp(rvec4 lo, rvec4 hi, rvec3 f) {
    rvec2 xy = rvec2(f.x, f.y);
    return dmBilerp(lo, xy) * (real(1) - f.z) + dmBilerp(hi, xy) * f.z;
}

// A ray bent by the base's curvature, in the slab's own coordinates (the top at z = L). Around
// the entry o (o.z = L) the shell is modelled by the quadric F = (1/2) e^T K e + (1/2) c z'^2 -
// z' (dmShellExit, meso_shade.h; c <= 0 the most convex principal curvature in voxels), which
// along the straight world ray from o is F(t) = bend t^2 - d.z t (dmShellBend gives the bend).
// On a ball or a cylinder F is a function of the depth D below the top alone, F = D + c D^2 / 2
// (so D = 2 F / (1 + sqrt(1 + 2 c F))), exactly at every depth; elsewhere it is the model. The
// ray's point in the slab is then P(t) = (o.x + d.x t, o.y + d.y t, L - D(F(t))): with c = 0
// the parabola o + t d - bend t^2 z, to the bit; bend 0 is the straight ray o + t d, whatever c
// is (and costs no more). t is the straight world ray's parameter, d unit and going down.
DM_TFUNC rvec3 dmBentPoint(rvec3 o, rvec3 d, real bend, real curve, real t) {
    rvec3 p = o + d * t;
    if (bend == real(0)) {
        return p;
    }
    // F - D(F) = 2 c F^2 / (1 + sqrt(1 + 2 c F))^2: no cancellation, 0 for c = 0.
    real f = bend * (t * t) - d.z * t;
    real q = real(1) + sqrt(max(real(1) + real(2) * curve * f, real(0)));
    return rvec3(p.x, p.y, (p.z - bend * (t * t)) + (real(2) * curve * (f * f)) / (q * q));
}

// The direction of that curve at t (not unit): (d.x, d.y, -D'(F) F'(t)), F' = 2 bend t - d.z,
// D'(F) = 1 / sqrt(1 + 2 c F); d itself for bend 0.
DM_TFUNC rvec3 dmBentTangent(rvec3 d, real bend, real curve, real t) {
    if (bend == real(0)) {
        return d;
    }
    real f = bend * (t * t) - d.z * t;
    return rvec3(d.x, d.y, -(real(2) * bend * t - d.z) / sqrt(max(real(1) + real(2) * curve * f, real(1e-30))));
}

// The largest rate D'(F) = 1 / sqrt(1 + 2 c F) of the depth along F (dmBentPoint) inside a slab
// L deep: at its floor, 1 / (1 + c L) (1 for c = 0; 2 at the renderer's limit, c L = -1/2).
DM_TFUNC real dmBentDepthRate(real curve, real L) {
    return real(1) / (real(1) + curve * L);
}

// Where that curve from o (o.z >= 0, d going down) meets the floor z = 0, D(F) = o.z: F =
// o.z + c o.z^2 / 2, the smaller root 2 F / (sqrt(d.z^2 + 4 bend F) - d.z) of bend t^2 - d.z t
// = F (the straight ray's dmPlaneHit for bend 0), or `none` where it has no root (a convex
// curve that turns up before the floor).
DM_TFUNC real dmBentFloor(rvec3 o, rvec3 d, real bend, real curve, real none) {
    if (bend == real(0)) {
        return dmPlaneHit(o, d, real(0));
    }
    real f = o.z + real(0.5) * curve * (o.z * o.z);
    real disc = d.z * d.z + real(4) * bend * f;
    return disc >= real(0) ? (real(2) * f) / (sqrt(disc) - d.z) : none;
}

// One sphere-tracing step (Hart 1996; Donnelly §8.3) with the interpolated distance `dist`
// at the point p of parameter t on the curve dmBentPoint(o, d, bend, curve, t) (bend 0: the
// straight ray), moving both on: returns 1 when converged (dist <= eps; a fixed iteration count passes eps <
// 0), 2 when the step leaves through the top (a miss), 0 to go on. For bend 0 the step is the
// distance itself; a bent ray's point moves at |(d_h, D' F')| <= sqrt(|d_h|^2 + V(tau)^2) per
// unit of tau, V = D'max (|d.z| + 2 |bend| tau) (dmBentDepthRate), so a step dt moves it by at
// most dt sqrt(|d_h|^2 + V(t)^2) + D'max |bend| dt^2, which the root of that = dist keeps within
// the distance read. A step below the bottom plane stops on it (1): the solid fills z < 0.
DM_TFUNC int dmSphereTraceStep(DM_INOUT(real) t, DM_INOUT(rvec3) p, real dist, real eps, rvec3 o, rvec3 d, real bend, real curve, int L) {
    if (dist <= eps) {
        return 1;
    }
    real r = max(dist, real(0));
    if (bend == real(0)) {
        t = t + r;
    } else {
        real rate = dmBentDepthRate(curve, real(L));
        real a = rate * abs(bend);
        real v = rate * (abs(d.z) + real(2) * abs(bend) * t);
        real s = sqrt(d.x * d.x + d.y * d.y + v * v);
        t = t + (real(2) * r) / (s + sqrt(s * s + real(4) * a * r));
    }
    p = dmBentPoint(o, d, bend, curve, t);
    if (p.z > real(L)) {
        return 2;
    }
    if (p.z < real(0)) {
        t = dmBentFloor(o, d, bend, curve, t); // (a convex curve rounded just below the floor may have no root: stay)
        p = dmBentPoint(o, d, bend, curve, t);
        return 1;
    }
    return 0;
}

// --- Conservative (directional) distance maps -----------------------------------------------
// One step of Algorithm 3.1 for a ray at o + t d in voxel v (inside the slab). `dist` is v's
// conservative distance in the ray's cone (from anywhere in v, the ray moving within the
// cone, no surface closer); qa, qb, qc the voxel's quadric (dmVoxelQuadric) in the frame with
// origin qo. dist == 0: the ray is tested against the quadric inside v (3.2), and moves to the
// next voxel when it misses (3.3). dist > 0: the paper steps t + dist (exitRule 0); exitRule 1
// steps exit(v) + dist, which is safe as well: a surface point m hit after the exit point e
// has m - e in the cone and e in v, so |m - e| >= dist; and no point inside v is hit, since
// dist > 0 says no surface point of v is reachable within the cone. With exitRule 1 it never
// stalls: every step crosses at least one voxel. Returns 1 with t at the hit, 0 with (t, v)
// advanced.
DM_TFUNC int dmDdmStep(DM_INOUT(real) t, DM_INOUT(ivec3) v, real dist, rvec4 qa, rvec4 qb, rvec4 qc, rvec3 qo, rvec3 o,
                       rvec3 d, int exitRule, real tol) {
    int axis;
    real tExit = dmVoxelExit(o, d, v, axis);
    if (dist <= real(0)) {
        real s;
        if (dmRayQuadric(qa, qb, qc, (o + d * t) - qo, d, max(tExit - t, real(0)), tol, s)) {
            t = t + s;
            return 1;
        }
        t = max(tExit, t);
        v = dmVoxelStep(v, d, axis);
        return 0;
    }
    real tNew = exitRule != 0 ? max(tExit, t) + dist : t + dist;
    ivec3 w = dmVoxelAt(o + d * tNew, d);
    if (w == v && tNew >= tExit) {
        w = dmVoxelStep(v, d, axis); // rounding left the point on v's side of the wall
    }
    t = tNew;
    v = w;
    return 0;
}

// --- Relief mapping and parallax occlusion mapping (height-field baselines) ----------------
// Texel cell of xy (unwrapped) and the bilinear fraction inside it.
DM_TFUNC ivec2 dmHeightCell(rvec2 xy, DM_OUT(rvec2) f) {
    rvec2 b = floor(xy);
    f = xy - b;
    return ivec2(int(b.x), int(b.y));
}

// Height of p above the surface, given the heights h of its cell (dmBilerp's order) and f.
DM_TFUNC real dmHeightAbove(rvec3 p, rvec4 h, rvec2 f) {
    return p.z - dmBilerp(h, f);
}

// Linear search of relief mapping and POM: the bracket (t_prev, t) advances by dt while the
// sample at t is above the surface; returns true when `above` (at bracket.y) is <= 0.
DM_TFUNC bool dmLinearSearchStep(DM_INOUT(rvec2) bracket, real dt, real above) {
    if (above <= real(0)) {
        return true;
    }
    bracket = rvec2(bracket.y, bracket.y + dt);
    return false;
}

// Relief mapping's binary search: given `above` at the bracket's midpoint, keep the half
// that still contains the crossing (the first end above, the second at or below).
DM_TFUNC rvec2 dmBisectStep(rvec2 bracket, real above) {
    real mid = real(0.5) * (bracket.x + bracket.y);
    return above <= real(0) ? rvec2(bracket.x, mid) : rvec2(mid, bracket.y);
}

// POM's final step (Tatarchuk 2006): where the segment between the last sample above
// (height aboveA > 0 at bracket.x) and the first below (aboveB <= 0 at bracket.y) crosses.
// A search that ran out above the surface (aboveB > 0: the last sample, summed in steps of
// dt, can stop just above a floor at height 0) stays at its last sample, bracket.x.
DM_TFUNC real dmPomIntersect(rvec2 bracket, real aboveA, real aboveB) {
    if (aboveB > real(0)) {
        return bracket.x;
    }
    real w = aboveA - aboveB;
    return w > real(0) ? bracket.x + (bracket.y - bracket.x) * (aboveA / w) : bracket.y;
}

// The compressed DDM (Mehra & Kumar §4, Appendix A): per cone a lookup grid of B^3 blocks. A
// grid word with bit 31 clear holds the bits of the block's one distance (a non-negative
// float, whose sign bit is 0: all its voxels read it); with bits 31 and 30 = 10 the block's
// index in the atlas (blocks a surface passes through, and blocks of free space no one value or
// plane bounds closely, stored in full); with 11 the offset, in floats of the atlas buffer, of
// the block's plane record (a0, gx, gy, gz: dmPlaneBlockDistance). Returns the one distance
// with kind 0, or -1 with kind 1 (atlasIndex the block) or 2 (atlasIndex the record's offset).
DM_FUNC float dmGridWordDistance(uint w, DM_OUT(int) atlasIndex, DM_OUT(int) kind) {
    atlasIndex = -1;
    kind = 0;
    if ((w >> 31u) != 0u) {
        kind = ((w >> 30u) & 1u) != 0u ? 2 : 1;
        atlasIndex = int(w & 0x3fffffffu);
        return float(-1.0);
    }
    return uintBitsToFloat(w);
}

// A plane block's distance at voxel f of the block (0 .. B - 1 along each axis): the plane
// a0 + gx f.x + gy f.y + gz f.z (added in that order), at least 0. compressDdm fits the plane
// below every value of the block (so the bound stays conservative) and checks it with this
// very function.
DM_FUNC float dmPlaneBlockDistance(float a0, float gx, float gy, float gz, ivec3 f) {
    return max(((a0 + gx * float(f.x)) + gy * float(f.y)) + gz * float(f.z), float(0.0));
}
// dispmap:glsl-end
} // namespace dispmap::kern
#include "dispmap/kernels/prelude_end.h"
