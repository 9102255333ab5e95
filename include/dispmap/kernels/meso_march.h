#pragma once
// The mesostructure marchers' loops, written once for the CPU (include/dispmap/meso/march.h)
// and the GPU (shaders/meso/march.glsl): Donnelly's sphere tracing of a distance map, Mehra &
// Kumar's Algorithm 3.1 over a conservative directional distance map (with the quadric of a
// voxel whose distance is 0), and relief mapping / parallax occlusion mapping. Every step is a
// kernel of kernels/meso.h; what is here is the loops and the order of their fetches.
//
// The includer supplies the memory. It defines the type DmMesoMaps (a value naming the maps
// and holding at least `int layers`) and these fetch functions before instantiating (C++) or
// including (GLSL) the kernels:
//   float dmMesoFetchDistance(DmMesoMaps m, int i, int j, int k)  DistanceMap::at (i, j wrapped)
//   float dmMesoFetchDdm(DmMesoMaps m, int c, int i, int j, int k) the DDM of cone c (wrapped)
//   vec4  dmMesoFetchCell(DmMesoMaps m, int i, int j)              MesoHeightField::cell
//   vec4  dmMesoFetchQuadric(DmMesoMaps m, int i, int j, int part) ColumnQuadrics::q[3 col + part]
//   uint  dmMesoFetchImage(DmMesoMaps m, int i)                    the images' words: MesoAlbedo::words[i]
//                                                                  (meso/albedo.h), albedo then normal map
//   ivec2 dmMesoFetchSolidRange(DmMesoMaps m, int i, int j, int k) a solid's entries in voxel (i, j, k)
//                                                                  (wrapped): [x, y) (meso/solid.h)
//   uint  dmMesoFetchSolidEntry(DmMesoMaps m, int e)               entry e: MesoSolid::entryWord
//   vec4  dmMesoFetchSolidTriangle(DmMesoMaps m, int t, int part)  triangle t: part 0 its first corner a,
//                                                                  1 and 2 its edges e1, e2 (xyz)
// and DmMesoMaps holds `int width, height` (the tile's voxels) for the solid's march.
// In GLSL DmMesoMaps is the includer's struct (march.glsl: #define DmMesoMaps DmMesoSize). In
// C++ it is DmMesoMapsT<real>, a class template this header only declares, so the fetch calls
// depend on the template parameter and are found at instantiation, in the includer's
// definitions (meso/march.h). Results: each marcher returns whether it hit and writes the ray
// parameter t of the hit (voxel units along the unit direction d) and its iteration count.
#include "dispmap/kernels/meso.h"
#include "dispmap/kernels/prelude.h"

namespace dispmap::kern {
/// The includer's view of the maps (C++): defined by dispmap/meso/march.h.
template <typename real> struct DmMesoMapsT;
} // namespace dispmap::kern
#define DmMesoMaps DmMesoMapsT<real>

namespace dispmap::kern {
// dispmap:glsl-begin check-with meso/march.glsl
// Where the bent ray from the top (dmBentPoint) ends: on the floor (dmBentFloor), or, bent up
// (bend < 0, convex), back at the top (F = 0) at t = d.z / bend when that comes first
// (endsAtTop: the ray has left the shell there).
DM_TFUNC real dmBentRayEnd(real L, rvec3 d, real bend, real curve, DM_OUT(bool) endsAtTop) {
    real tEnd = dmBentFloor(rvec3(real(0), real(0), L), d, bend, curve, real(-1));
    endsAtTop = false;
    if (bend < real(0)) {
        real tTop = d.z / bend;
        endsAtTop = tEnd < real(0) || tTop < tEnd;
        tEnd = endsAtTop ? tTop : tEnd;
    }
    return tEnd;
}

// Donnelly's sphere tracing along the curve dmBentPoint(o, d, bend, curve, t) (bend 0: the
// straight ray): `iterations` steps of the trilinearly read distance, or fewer when it falls to eps or
// below (dmSphereTraceStep: each step moves the point along the curve no farther than the
// distance read). The hit is where the last step ends (tHit its parameter, pHit the point); a
// curve that rose through the top is a miss.
DM_TFUNC bool dmMesoMarchDistanceBent(DmMesoMaps m, rvec3 o, rvec3 d, real bend, real curve, int iterations, real eps,
                                      DM_OUT(real) tHit, DM_OUT(rvec3) pHit, DM_OUT(int) count) {
    count = 0;
    real t = real(0);
    rvec3 p = o;
    int status = 0;
    for (int i = 0; i < iterations && status == 0; ++i) {
        rvec3 f;
        ivec3 c = dmDistanceSampleCell(p, m.layers, f);
        rvec4 lo = rvec4(real(dmMesoFetchDistance(m, c.x, c.y, c.z)), real(dmMesoFetchDistance(m, c.x + 1, c.y, c.z)),
                         real(dmMesoFetchDistance(m, c.x + 1, c.y + 1, c.z)), real(dmMesoFetchDistance(m, c.x, c.y + 1, c.z)));
        rvec4 hi = rvec4(real(dmMesoFetchDistance(m, c.x, c.y, c.z + 1)), real(dmMesoFetchDistance(m, c.x + 1, c.y, c.z + 1)),
                         real(dmMesoFetchDistance(m, c.x + 1, c.y + 1, c.z + 1)),
                         real(dmMesoFetchDistance(m, c.x, c.y + 1, c.z + 1)));
        count = count + 1;
        status = dmSphereTraceStep(t, p, dmTrilerp(lo, hi, f), eps, o, d, bend, curve, m.layers);
    }
    tHit = t;
    pHit = p;
    return status != 2;
}

// Donnelly's sphere tracing along the straight ray (dmMesoMarchDistanceBent with bend 0).
DM_TFUNC bool dmMesoMarchDistance(DmMesoMaps m, rvec3 o, rvec3 d, int iterations, real eps, DM_OUT(real) tHit,
                                  DM_OUT(int) count) {
    rvec3 p;
    return dmMesoMarchDistanceBent(m, o, d, real(0), real(0), iterations, eps, tHit, p, count);
}

// Algorithm 3.1 (sphere tracing a conservative DDM, quadric intersection 3.2, voxel walls 3.3)
// with the cones coneM x coneN (dmConeIndex). quadrics: intersect the quadric in a voxel whose
// distance is 0 (else stop there). A ray that runs out of iterations counts as a hit at its
// last point (short of the surface: conservative), so a shadow ray never leaks light and a
// view ray never shows the sky through the surface. exitRule and tol: dmDdmStep. tMax: the
// march stops, as a miss with t > tMax, once it has passed tMax (a chord of a bent ray:
// dmMesoMarchDdmBent; a hit found beyond it is returned as it is, t > tMax). A straight march
// passes 3.0e38, no limit.
DM_TFUNC bool dmMesoMarchDdm(DmMesoMaps m, rvec3 o, rvec3 d, int coneM, int coneN, int maxIterations, bool quadrics,
                             int exitRule, real tol, real tMax, DM_OUT(real) tHit, DM_OUT(int) count) {
    int cone = dmConeIndex(d, coneM, coneN);
    bool hit = true; // until the ray leaves: running out of iterations is a hit (see above)
    count = 0;
    real t = real(0);
    ivec3 v = dmVoxelAt(o, d);
    for (int i = 0; i < maxIterations; ++i) {
        bool below;
        if (dmDdmLeftSlab(v, m.layers, o, d, t, below)) {
            hit = below;
            break;
        }
        if (t > tMax) {
            hit = false;
            break;
        }
        count = count + 1;
        real dist = real(dmMesoFetchDdm(m, cone, v.x, v.y, v.z));
        rvec4 qa = rvec4(real(0)); // without quadrics a 0 voxel is the hit
        rvec4 qb = rvec4(real(0));
        rvec4 qc = rvec4(real(0), real(1), real(0), real(0));
        if (dist <= real(0) && quadrics) {
            dmVoxelQuadric(rvec4(dmMesoFetchQuadric(m, v.x, v.y, 0)), rvec4(dmMesoFetchQuadric(m, v.x, v.y, 1)),
                           rvec4(dmMesoFetchQuadric(m, v.x, v.y, 2)), v.z, qa, qb, qc);
        }
        rvec3 qo = rvec3(real(v.x), real(v.y), real(0));
        if (dmDdmStep(t, v, dist, qa, qb, qc, qo, o, d, exitRule, tol) == 1) {
            hit = true;
            break;
        }
    }
    tHit = t;
    return hit;
}

// Algorithm 3.1 over a solid (non-height-field detail, meso/solid.h): the march of
// dmMesoMarchDdm where a voxel whose distance is 0 tests the ray exactly against the triangles
// listed for it and moves on to the next voxel when none is crossed inside it. An entry names
// its triangle and the tile of the copy next to the voxel it was listed from, so the copy next
// to this voxel v is the triangle shifted by whole tiles (no periodic shift is searched), and
// the test runs in v's frame (origin its lower corner) to keep float's digits. A crossing
// counts within tol (1 + t) of the voxel's span: a face on a voxel wall is listed on both
// sides, and the two frames round its t differently. The floor z < 0 is solid. Writes the
// triangle hit (-1: the floor, or running out of iterations) and the barycentric uv there;
// one iteration per voxel visited, whatever its triangle count. tMax: as dmMesoMarchDdm (a
// chord of a bent ray; a crossing found beyond it in the voxel where it stops is returned).
DM_TFUNC bool dmMesoMarchDdmSolid(DmMesoMaps m, rvec3 o, rvec3 d, int coneM, int coneN, int maxIterations, int exitRule, real tol,
                                  real tMax, DM_OUT(real) tHit, DM_OUT(int) count, DM_OUT(int) triangle, DM_OUT(rvec2) uv) {
    int cone = dmConeIndex(d, coneM, coneN);
    bool hit = true; // until the ray leaves, as dmMesoMarchDdm
    count = 0;
    triangle = -1;
    uv = rvec2(real(0));
    real t = real(0);
    ivec3 v = dmVoxelAt(o, d);
    rvec4 none = rvec4(real(0));
    for (int i = 0; i < maxIterations; ++i) {
        bool below;
        if (dmDdmLeftSlab(v, m.layers, o, d, t, below)) {
            hit = below;
            break;
        }
        if (t > tMax) {
            hit = false;
            break;
        }
        count = count + 1;
        real dist = real(dmMesoFetchDdm(m, cone, v.x, v.y, v.z));
        if (dist <= real(0)) {
            int axis;
            real tExit = max(dmVoxelExit(o, d, v, axis), t);
            real slack = tol * (real(1) + t);
            real tBest = tExit + slack;
            ivec2 range = dmMesoFetchSolidRange(m, v.x, v.y, v.z);
            rvec3 ol = o - rvec3(real(v.x), real(v.y), real(v.z));
            ivec2 tileV = ivec2(dmFloorDiv(v.x, m.width), dmFloorDiv(v.y, m.height));
            int found = -1;
            for (int e = range.x; e < range.y; ++e) {
                uint w = dmMesoFetchSolidEntry(m, e);
                int tri = int(w & 16777215u);
                // The copy's corner in v's frame: the triangle's own corner less v moved back
                // by the tiles between the entry's copy and v (integers: exact).
                ivec3 back = ivec3(v.x - (tileV.x - (int((w >> 24u) & 15u) - 8)) * m.width,
                                   v.y - (tileV.y - (int(w >> 28u) - 8)) * m.height, v.z);
                rvec3 a = rvec3(dmMesoFetchSolidTriangle(m, tri, 0)) - rvec3(real(back.x), real(back.y), real(back.z));
                rvec3 e1 = rvec3(dmMesoFetchSolidTriangle(m, tri, 1));
                rvec3 e2 = rvec3(dmMesoFetchSolidTriangle(m, tri, 2));
                if (dmRayTriangle(ol, d, a, e1, e2, t - slack, tBest, uv)) {
                    found = tri;
                }
            }
            if (found >= 0) {
                triangle = found;
                t = max(tBest, real(0));
                break;
            }
            t = tExit; // no crossing inside: on to the next voxel (Algorithm 3.3)
            v = dmVoxelStep(v, d, axis);
        } else {
            dmDdmStep(t, v, dist, none, none, none, rvec3(real(0)), o, d, exitRule, tol);
        }
    }
    tHit = t;
    return hit;
}

// The DDM march along a ray bent by the base's curvature (Donnelly's locally planar model with
// the quadric of the shell's top, kern::dmShellBend): in the slab's own coordinates, where the
// top lies at z = L everywhere, the straight world ray from the entry o (o.z = L, d going down,
// unit) is the curve dmBentPoint(o, d, bend, curve, t) (with curve 0 the parabola o + t d -
// bend t^2 z). It ends on the floor (z = 0) or, bent up (bend < 0, convex), back at the top,
// where it has left the shell: a miss, the silhouette of the detail itself. It is marched as
// chords of equal parameter length, each a straight dmMesoMarchDdm (a height field's, with its
// quadrics) or, with `solid`, dmMesoMarchDdmSolid (a solid's triangles) that stops past the
// chord's end, as few as keep every chord within `chordError` voxels of the curve (z'' len^2 /
// 8 for a chord of parameter length len, z'' <= D' 2 |bend| + |c| D'^3 F'^2 with D' =
// dmBentDepthRate and F' = 2 bend t - d.z at its largest; with curve 0, |bend| len^2 / 4), at
// most 64; the last chord goes on straight when the curve ends on the floor, and ends at the
// top when it comes back there (a miss). A hit on a chord is the hit; a chord that leaves
// through the top misses. Writes the hit's parameter on the straight ray (tHit: the world point
// is the straight ray's there) and its point in the slab's coordinates (pHit: where the detail
// is read), the iterations of all chords together (at most maxIterations; running out is a
// hit, as dmMesoMarchDdm) and, for a solid, the triangle hit and its barycentric uv (-1 and 0
// for the floor, a miss or a height field). bend == 0 is the straight march itself.
DM_TFUNC bool dmMesoMarchDdmBent(DmMesoMaps m, rvec3 o, rvec3 d, real bend, real curve, int coneM, int coneN, int maxIterations,
                                 bool quadrics, bool solid, int exitRule, real tol, real chordError, DM_OUT(real) tHit,
                                 DM_OUT(rvec3) pHit, DM_OUT(int) count, DM_OUT(int) triangle, DM_OUT(rvec2) uv) {
    bool endsAtTop; // bent back up to the top before the floor: out of the shell
    real tEnd = dmBentRayEnd(real(m.layers), d, bend, curve, endsAtTop);
    triangle = -1;
    uv = rvec2(real(0));
    if (bend == real(0)) {
        bool straight = solid ? dmMesoMarchDdmSolid(m, o, d, coneM, coneN, maxIterations, exitRule, tol, real(3.0e38), tHit, count, triangle, uv)
                              : dmMesoMarchDdm(m, o, d, coneM, coneN, maxIterations, quadrics, exitRule, tol, real(3.0e38), tHit, count);
        pHit = o + d * tHit;
        return straight;
    }
    real rate = dmBentDepthRate(curve, real(m.layers));
    real slope = max(abs(d.z), abs(real(2) * bend * tEnd - d.z));
    real zpp = rate * (real(2) * abs(bend) + abs(curve) * (rate * rate) * (slope * slope));
    int chords = max(int(min(ceil(tEnd * sqrt(zpp / (real(8) * chordError))), real(64))), 1);
    count = 0;
    tHit = real(0);
    pHit = o;
    for (int k = 0; k < chords; ++k) {
        real ta = tEnd * (real(k) / real(chords));
        real tb = tEnd * (real(k + 1) / real(chords));
        rvec3 pa = dmBentPoint(o, d, bend, curve, ta);
        rvec3 pb = dmBentPoint(o, d, bend, curve, tb);
        rvec3 u = pb - pa;
        real len = sqrt(dmDot3(u, u));
        if (!(len > real(0))) {
            // A chord shorter than float resolves (a ray grazing a convex top): it leaves there.
            tHit = ta;
            pHit = pa;
            return false;
        }
        u = u * (real(1) / len);
        bool last = k == chords - 1;
        // The last chord of a ray that reaches the floor goes on straight; one that comes back
        // to the top ends there too (rounding may leave its end a float step inside, and a
        // march along the top layer must not run on).
        real tMax = last && !endsAtTop ? real(3.0e38) : len;
        real tc;
        int used;
        bool hit = solid ? dmMesoMarchDdmSolid(m, pa, u, coneM, coneN, maxIterations - count, exitRule, tol, tMax, tc, used, triangle, uv)
                         : dmMesoMarchDdm(m, pa, u, coneM, coneN, maxIterations - count, quadrics, exitRule, tol, tMax, tc, used);
        count = count + used;
        tHit = ta + (tb - ta) * (tc / len);
        pHit = pa + u * tc;
        if (hit && tc <= tMax) {
            return true;
        }
        if (!hit && tc <= tMax) {
            return false; // out through the top within the chord
        }
        if (count >= maxIterations) {
            // Out of iterations: a hit where it stopped (conservative), on this chord (a crossing
            // found past its end is not this chord's: not a triangle hit either).
            real tk = min(tc, len);
            tHit = ta + (tb - ta) * (tk / len);
            pHit = pa + u * tk;
            triangle = -1;
            uv = rvec2(real(0));
            return true;
        }
    }
    // Only a ray bent back to the top gets here: it has left the shell.
    tHit = tEnd;
    pHit = dmBentPoint(o, d, bend, curve, tEnd);
    triangle = -1;
    uv = rvec2(real(0));
    return false;
}

// Height of the point p above the height field (one fetch, counted).
DM_TFUNC real dmMesoAboveAt(DmMesoMaps m, rvec3 p, DM_INOUT(int) count) {
    rvec2 f;
    ivec2 c = dmHeightCell(rvec2(p.x, p.y), f);
    count = count + 1;
    return dmHeightAbove(p, rvec4(dmMesoFetchCell(m, c.x, c.y)), f);
}

// The linear search of relief mapping and POM along the curve dmBentPoint(o, d, bend, curve, t)
// (bend 0: the straight ray o + t d): `steps` equal steps of t from 0 to tEnd until a sample is at or
// below the surface, then `binary` bisections of the last step (the hit the final bracket's
// midpoint) or, with binary < 0, POM's crossing of the segment between the last two samples. A
// curve that ends at the top (endsAtTop: bent back up, out of the shell) with no sample at or
// below the surface is a miss at tEnd.
DM_TFUNC bool dmMesoHeightSearch(DmMesoMaps m, rvec3 o, rvec3 d, real bend, real curve, real tEnd, int steps, bool endsAtTop,
                                 int binary, DM_OUT(real) tHit, DM_OUT(int) count) {
    count = 0;
    real dt = tEnd / real(steps);
    rvec2 bracket = rvec2(real(0), dt);
    real abovePrev = real(0);
    if (binary < 0) {
        abovePrev = dmMesoAboveAt(m, dmBentPoint(o, d, bend, curve, real(0)), count);
    }
    real aboveCur = real(0);
    bool crossed = false;
    for (int i = 0; i < steps; ++i) {
        aboveCur = dmMesoAboveAt(m, dmBentPoint(o, d, bend, curve, bracket.y), count);
        real keep = aboveCur;
        if (dmLinearSearchStep(bracket, dt, aboveCur)) {
            crossed = true;
            break;
        }
        abovePrev = keep;
    }
    if (endsAtTop && !crossed) {
        tHit = tEnd;
        return false;
    }
    if (binary < 0) {
        tHit = dmPomIntersect(bracket, abovePrev, aboveCur);
        return true;
    }
    for (int j = 0; j < binary; ++j) {
        real mid = real(0.5) * (bracket.x + bracket.y);
        bracket = dmBisectStep(bracket, dmMesoAboveAt(m, dmBentPoint(o, d, bend, curve, mid), count));
    }
    tHit = real(0.5) * (bracket.x + bracket.y);
    return true;
}

// Relief mapping (Policarpo et al. 2005): `linear` equal steps from the top to the bottom
// plane until a sample is at or below the surface, then `binary` bisections; the hit is the
// final bracket's midpoint. Parallax occlusion mapping (Tatarchuk 2006) with binary < 0: the
// same linear search, then the crossing of the segment between the last two samples. View
// rays only (d.z < 0) and linear >= 1: the caller checks.
DM_TFUNC bool dmMesoMarchHeight(DmMesoMaps m, rvec3 o, rvec3 d, int linear, int binary, DM_OUT(real) tHit,
                                DM_OUT(int) count) {
    return dmMesoHeightSearch(m, o, d, real(0), real(0), dmPlaneHit(o, d, real(0)), linear, false, binary, tHit, count);
}

// Relief mapping and POM (dmMesoMarchHeight) along a ray bent by the base's curvature: the
// curve dmBentPoint (with curve 0 a parabola) from the entry o at the top, equal steps of its
// parameter from the top to where it ends (dmBentRayEnd: the floor, or the top again when a convex base bends it back up),
// then the bisections or POM's crossing on the same curve (dmMesoHeightSearch). The steps are
// `linear`, or more where the curve is longer than the straight ray to the floor: never
// longer than the straight ray's steps (so thin walls are stepped over no more often than by the
// planar march), at most 4 linear (the most there can be: a convex parabola that just misses the
// floor, d.z^2 = 4 |bend| F at the floor's F <= L, is 4 times as long as the straight ray). A ray bent back up with no
// sample at or below the surface has left the shell: a miss (tHit, pHit its end). Writes the
// hit's parameter on the straight ray (tHit: the world point is the straight ray's there) and
// its point in the slab's coordinates (pHit: where the detail is read). bend == 0 is
// dmMesoMarchHeight itself. View rays only (o.z = L, d.z < 0) and linear >= 1: the caller
// checks.
DM_TFUNC bool dmMesoMarchHeightBent(DmMesoMaps m, rvec3 o, rvec3 d, real bend, real curve, int linear, int binary,
                                    DM_OUT(real) tHit, DM_OUT(rvec3) pHit, DM_OUT(int) count) {
    if (bend == real(0)) {
        bool straight = dmMesoMarchHeight(m, o, d, linear, binary, tHit, count);
        pHit = o + d * tHit;
        return straight;
    }
    bool endsAtTop;
    real tEnd = dmBentRayEnd(real(m.layers), d, bend, curve, endsAtTop);
    real straightStep = dmPlaneHit(o, d, real(0)) / real(linear);
    int steps = max(linear, int(min(ceil(tEnd / straightStep), real(4 * linear))));
    bool hit = dmMesoHeightSearch(m, o, d, bend, curve, tEnd, steps, endsAtTop, binary, tHit, count);
    pHit = dmBentPoint(o, d, bend, curve, tHit);
    return hit;
}

// --- Images over a tile: the albedo and the normal map (meso/albedo.h: MesoAlbedo's words) ----
// The images' words hold each image's own words from a base word `image` on (the renderer
// puts the albedo at 0 and the normal map after it); offsets in an image are its own.
// An RGBA8 texel, red in the lowest byte, as four values in [0, 1].
DM_TFUNC rvec4 dmUnpackRgba8(uint w, real unit) {
    return rvec4(real(w & 255u), real((w >> 8u) & 255u), real((w >> 16u) & 255u), real(w >> 24u)) / unit;
}

// The mip level of a pixel's footprint: dx, dy the texture coordinate's change (tiles) to the
// next pixel in x and y (the derivatives of the base's texture coordinate), size level 0's
// texels; log2 of the longer footprint in texels, at least 0.
DM_TFUNC real dmMesoImageLod(rvec2 dx, rvec2 dy, rvec2 size) {
    rvec2 a = dx * size;
    rvec2 b = dy * size;
    real m = max(a.x * a.x + a.y * a.y, b.x * b.x + b.y * b.y);
    return m > real(1) ? real(0.5) * log2(m) : real(0);
}

// Level `level` of the image from word `image` on, at texture coordinate uv (tiles; the image
// repeats), bilinear. Level 0's texel (x, y) sits at (x / w, y / h) of the tile, where the
// height field's sample (x W / w, y H / h) is (an image paired with the height image covers
// each height sample with its own pixel); a coarser level's texel sits at the mean of the
// level-0 texels it averages: p = uv size - 1/2 + size / (2 size0) along each axis.
DM_TFUNC rvec4 dmMesoImageBilinear(DmMesoMaps m, int image, int level, rvec2 uv) {
    int offset = image + int(dmMesoFetchImage(m, image + 1 + 4 * level));
    int w = int(dmMesoFetchImage(m, image + 2 + 4 * level));
    int h = int(dmMesoFetchImage(m, image + 3 + 4 * level));
    rvec2 size0 = rvec2(real(int(dmMesoFetchImage(m, image + 2))), real(int(dmMesoFetchImage(m, image + 3))));
    rvec2 p = rvec2(uv.x * real(w) - real(0.5) + real(0.5) * real(w) / size0.x, uv.y * real(h) - real(0.5) + real(0.5) * real(h) / size0.y);
    rvec2 c = floor(p);
    rvec2 f = p - c;
    // The cell's corners, wrapped: the lower corner's residue first, its neighbour one more
    // (mod the size), so no coordinate overflows however far uv is from the origin.
    int x0 = int(c.x - floor(c.x / real(w)) * real(w));
    int y0 = int(c.y - floor(c.y / real(h)) * real(h));
    x0 = min(max(x0, 0), w - 1);
    y0 = min(max(y0, 0), h - 1);
    int x1 = x0 + 1 == w ? 0 : x0 + 1;
    int y1 = y0 + 1 == h ? 0 : y0 + 1;
    real unit = real(255);
    rvec4 a = dmUnpackRgba8(dmMesoFetchImage(m, offset + y0 * w + x0), unit);
    rvec4 b = dmUnpackRgba8(dmMesoFetchImage(m, offset + y0 * w + x1), unit);
    rvec4 cc = dmUnpackRgba8(dmMesoFetchImage(m, offset + y1 * w + x1), unit);
    rvec4 d = dmUnpackRgba8(dmMesoFetchImage(m, offset + y1 * w + x0), unit);
    rvec4 lo = a + (b - a) * f.x;
    rvec4 hi = d + (cc - d) * f.x;
    return lo + (hi - lo) * f.y;
}

// Trilinear: the two levels around lod (clamped to the pyramid), mixed, read at uv moved by
// the image's shift (meso/albedo.h).
DM_TFUNC rvec4 dmMesoImage(DmMesoMaps m, int image, rvec2 uv, real lod) {
    int levels = int(dmMesoFetchImage(m, image));
    // The image's shift (level 0's texels), as a texture offset: every level reads the same point.
    rvec2 shift = rvec2(real(uintBitsToFloat(dmMesoFetchImage(m, image + 1 + 4 * levels))),
                        real(uintBitsToFloat(dmMesoFetchImage(m, image + 2 + 4 * levels))));
    rvec2 at = uv + rvec2(shift.x / real(int(dmMesoFetchImage(m, image + 2))), shift.y / real(int(dmMesoFetchImage(m, image + 3))));
    real l = min(max(lod, real(0)), real(levels - 1));
    int l0 = int(floor(l));
    int l1 = min(l0 + 1, levels - 1);
    real f = l - real(l0);
    rvec4 a = dmMesoImageBilinear(m, image, l0, at);
    if (l1 == l0 || f == real(0)) {
        return a;
    }
    rvec4 b = dmMesoImageBilinear(m, image, l1, at);
    return a + (b - a) * f;
}
// dispmap:glsl-end
} // namespace dispmap::kern
#undef DmMesoMaps
#include "dispmap/kernels/prelude_end.h"
