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
// Donnelly's sphere tracing: `iterations` steps of the trilinearly read distance, or fewer
// when it falls to eps or below (dmSphereTraceStep). The hit is where the last step ends; a
// ray that rose through the top is a miss.
DM_TFUNC bool dmMesoMarchDistance(DmMesoMaps m, rvec3 o, rvec3 d, int iterations, real eps, DM_OUT(real) tHit,
                                  DM_OUT(int) count) {
    count = 0;
    real t = real(0);
    int status = 0;
    for (int i = 0; i < iterations && status == 0; ++i) {
        rvec3 f;
        ivec3 c = dmDistanceSampleCell(o + d * t, m.layers, f);
        rvec4 lo = rvec4(real(dmMesoFetchDistance(m, c.x, c.y, c.z)), real(dmMesoFetchDistance(m, c.x + 1, c.y, c.z)),
                         real(dmMesoFetchDistance(m, c.x + 1, c.y + 1, c.z)), real(dmMesoFetchDistance(m, c.x, c.y + 1, c.z)));
        rvec4 hi = rvec4(real(dmMesoFetchDistance(m, c.x, c.y, c.z + 1)), real(dmMesoFetchDistance(m, c.x + 1, c.y, c.z + 1)),
                         real(dmMesoFetchDistance(m, c.x + 1, c.y + 1, c.z + 1)),
                         real(dmMesoFetchDistance(m, c.x, c.y + 1, c.z + 1)));
        count = count + 1;
        status = dmSphereTraceStep(t, dmTrilerp(lo, hi, f), eps, o, d, m.layers);
    }
    tHit = t;
    return status != 2;
}

// Algorithm 3.1 (sphere tracing a conservative DDM, quadric intersection 3.2, voxel walls 3.3)
// with the cones coneM x coneN (dmConeIndex). quadrics: intersect the quadric in a voxel whose
// distance is 0 (else stop there). A ray that runs out of iterations counts as a hit at its
// last point (short of the surface: conservative), so a shadow ray never leaks light and a
// view ray never shows the sky through the surface. exitRule and tol: dmDdmStep.
DM_TFUNC bool dmMesoMarchDdm(DmMesoMaps m, rvec3 o, rvec3 d, int coneM, int coneN, int maxIterations, bool quadrics,
                             int exitRule, real tol, DM_OUT(real) tHit, DM_OUT(int) count) {
    int cone = dmConeIndex(d, coneM, coneN);
    bool hit = true; // until the ray leaves: running out of iterations is a hit (see above)
    count = 0;
    real t = real(0);
    ivec3 v = dmVoxelAt(o, d);
    for (int i = 0; i < maxIterations; ++i) {
        int slab = dmSlabStatus(v, m.layers);
        if (slab != 0) {
            hit = slab == 1;
            if (hit && d.z < real(0)) {
                t = max(t, dmPlaneHit(o, d, real(0)));
            }
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

// Height of the point at t above the height field (one fetch, counted).
DM_TFUNC real dmMesoAbove(DmMesoMaps m, rvec3 o, rvec3 d, real t, DM_INOUT(int) count) {
    rvec3 p = o + d * t;
    rvec2 f;
    ivec2 c = dmHeightCell(rvec2(p.x, p.y), f);
    count = count + 1;
    return dmHeightAbove(p, rvec4(dmMesoFetchCell(m, c.x, c.y)), f);
}

// Relief mapping (Policarpo et al. 2005): `linear` equal steps from the top to the bottom
// plane until a sample is at or below the surface, then `binary` bisections; the hit is the
// final bracket's midpoint. Parallax occlusion mapping (Tatarchuk 2006) with binary < 0: the
// same linear search, then the crossing of the segment between the last two samples. View
// rays only (d.z < 0) and linear >= 1: the caller checks.
DM_TFUNC bool dmMesoMarchHeight(DmMesoMaps m, rvec3 o, rvec3 d, int linear, int binary, DM_OUT(real) tHit,
                                DM_OUT(int) count) {
    count = 0;
    real tEnd = dmPlaneHit(o, d, real(0));
    real dt = tEnd / real(linear);
    rvec2 bracket = rvec2(real(0), dt);
    real abovePrev = real(0);
    if (binary < 0) {
        abovePrev = dmMesoAbove(m, o, d, real(0), count);
    }
    real aboveCur = real(0);
    for (int i = 0; i < linear; ++i) {
        aboveCur = dmMesoAbove(m, o, d, bracket.y, count);
        real keep = aboveCur;
        if (dmLinearSearchStep(bracket, dt, aboveCur)) {
            break;
        }
        abovePrev = keep;
    }
    if (binary < 0) {
        tHit = dmPomIntersect(bracket, abovePrev, aboveCur);
        return true;
    }
    for (int j = 0; j < binary; ++j) {
        bracket = dmBisectStep(bracket, dmMesoAbove(m, o, d, real(0.5) * (bracket.x + bracket.y), count));
    }
    tHit = real(0.5) * (bracket.x + bracket.y);
    return true;
}
// dispmap:glsl-end
} // namespace dispmap::kern
#undef DmMesoMaps
#include "dispmap/kernels/prelude_end.h"
