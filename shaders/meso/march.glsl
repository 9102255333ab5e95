// The mesostructure marchers on the GPU: the twin of include/dispmap/meso/march.h
// (marchDistanceMap, marchDdm over the compressed map, marchHeightSearch), statement by
// statement, so that lavapipe (which does not fuse multiply-adds; the C++ side is built with
// -ffp-contract=off) gives the same hits, parameters and iteration counts bit for bit.
// Only loops and memory reads live here; every formula is a kernel of kernels/meso.h.
//
// The includer defines DM_MESO_SET and DM_MESO_BINDING (the first of five consecutive
// storage-buffer bindings) before including this file, and fills a DmMesoSize from the host
// (backend_vulkan: mesoSize()). The buffers, std430, as the host maps hold them:
//   +0 heights    MesoHeightField::h, W x H floats, x fastest
//   +1 distances  DistanceMap::d, [k][j][i] floats
//   +2 grid       CompressedDdm::grid, [cone][bz][by][bx] uint words
//   +3 atlas      CompressedDdm::atlas, blocks of block^3 floats, x fastest
//   +4 quadrics   ColumnQuadrics::q, three vec4 per column, x fastest
// A buffer a pipeline does not read may be a 16-byte placeholder.
#ifndef DISPMAP_MESO_MARCH_GLSL
#define DISPMAP_MESO_MARCH_GLSL
#include "meso.glsl"

#ifndef DM_MESO_SET
#define DM_MESO_SET 0
#endif
#ifndef DM_MESO_BINDING
#define DM_MESO_BINDING 0
#endif

layout(std430, set = DM_MESO_SET, binding = DM_MESO_BINDING + 0) readonly buffer DmMesoHeights { float dmMesoHeights[]; };
layout(std430, set = DM_MESO_SET, binding = DM_MESO_BINDING + 1) readonly buffer DmMesoDistances { float dmMesoDistances[]; };
layout(std430, set = DM_MESO_SET, binding = DM_MESO_BINDING + 2) readonly buffer DmMesoGrid { uint dmMesoGrid[]; };
layout(std430, set = DM_MESO_SET, binding = DM_MESO_BINDING + 3) readonly buffer DmMesoAtlas { float dmMesoAtlas[]; };
layout(std430, set = DM_MESO_SET, binding = DM_MESO_BINDING + 4) readonly buffer DmMesoQuadrics { vec4 dmMesoQuadrics[]; };

// The sizes of the maps (all share W x H x L) and the root tolerance
// (mesoRootTolerance<float>(), passed by the host, never retyped here).
struct DmMesoSize {
    int width;
    int height;
    int layers;
    int block; // CompressedDdm::block
    int gx;    // grid size in blocks
    int gy;
    int gz;
    int coneM; // ConeSet::kernelM()
    int coneN; // ConeSet::n
    float tol;
};

struct DmMesoHit {
    bool hit;
    float t;
    int iterations;
};

// detail::wrapIndex: the non-negative residue of i modulo n > 0, exact for every int (GLSL's
// % is undefined for negative operands; ~i = -i - 1 never overflows).
int dmMesoWrap(int i, int n) {
    return i >= 0 ? i % n : (n - 1) - (~i % n);
}

// MesoHeightField::at and ::cell.
float dmMesoHeightAt(DmMesoSize s, int x, int y) {
    return dmMesoHeights[dmMesoWrap(y, s.height) * s.width + dmMesoWrap(x, s.width)];
}
vec4 dmMesoCell(DmMesoSize s, int i, int j) {
    return vec4(dmMesoHeightAt(s, i, j), dmMesoHeightAt(s, i + 1, j), dmMesoHeightAt(s, i + 1, j + 1), dmMesoHeightAt(s, i, j + 1));
}

// DistanceMap::at (k in [0, layers)).
float dmMesoDistanceAt(DmMesoSize s, int i, int j, int k) {
    return dmMesoDistances[(k * s.height + dmMesoWrap(j, s.height)) * s.width + dmMesoWrap(i, s.width)];
}

// CompressedDdm::lookup (Appendix A.2), k in [0, layers).
float dmMesoDdmLookup(DmMesoSize s, int c, int i0, int j0, int k) {
    int i = dmMesoWrap(i0, s.width);
    int j = dmMesoWrap(j0, s.height);
    int atlasIndex = -1;
    int b = s.block;
    float d = dmGridWordDistance(dmMesoGrid[((c * s.gz + k / b) * s.gy + j / b) * s.gx + i / b], atlasIndex);
    if (atlasIndex < 0) {
        return d;
    }
    return dmMesoAtlas[atlasIndex * (b * b * b) + ((k % b) * b + j % b) * b + i % b];
}

// marchDistanceMap<float>.
DmMesoHit dmMarchDistanceMap(DmMesoSize s, vec3 o, vec3 d, int iterations, float eps) {
    DmMesoHit r;
    r.hit = false;
    r.iterations = 0;
    float t = 0.0;
    int status = 0;
    for (int i = 0; i < iterations && status == 0; ++i) {
        vec3 f;
        ivec3 c = dmDistanceSampleCell(o + d * t, s.layers, f);
        vec4 lo = vec4(dmMesoDistanceAt(s, c.x, c.y, c.z), dmMesoDistanceAt(s, c.x + 1, c.y, c.z),
                       dmMesoDistanceAt(s, c.x + 1, c.y + 1, c.z), dmMesoDistanceAt(s, c.x, c.y + 1, c.z));
        vec4 hi = vec4(dmMesoDistanceAt(s, c.x, c.y, c.z + 1), dmMesoDistanceAt(s, c.x + 1, c.y, c.z + 1),
                       dmMesoDistanceAt(s, c.x + 1, c.y + 1, c.z + 1), dmMesoDistanceAt(s, c.x, c.y + 1, c.z + 1));
        ++r.iterations;
        status = dmSphereTraceStep(t, dmTrilerp(lo, hi, f), eps, o, d, s.layers);
    }
    r.hit = status != 2;
    r.t = t;
    return r;
}

// marchDdm<float> over CompressedDdmView (the host checks the shadow-cone and quadric
// preconditions).
DmMesoHit dmMarchDdm(DmMesoSize s, vec3 o, vec3 d, int maxIterations, bool quadrics, int exitRule) {
    int cone = dmConeIndex(d, s.coneM, s.coneN);
    DmMesoHit r;
    r.hit = true; // until the ray leaves: running out of iterations is a hit (as marchDdm)
    r.iterations = 0;
    float t = 0.0;
    ivec3 v = dmVoxelAt(o, d);
    for (int i = 0; i < maxIterations; ++i) {
        int slab = dmSlabStatus(v, s.layers);
        if (slab != 0) {
            r.hit = slab == 1;
            if (r.hit && d.z < 0.0) {
                t = max(t, dmPlaneHit(o, d, 0.0));
            }
            break;
        }
        ++r.iterations;
        float dist = dmMesoDdmLookup(s, cone, v.x, v.y, v.z);
        vec4 qa = vec4(0.0); // without quadrics a 0 voxel is the hit
        vec4 qb = vec4(0.0);
        vec4 qc = vec4(0.0, 1.0, 0.0, 0.0);
        if (dist <= 0.0 && quadrics) {
            int at = 3 * (dmMesoWrap(v.y, s.height) * s.width + dmMesoWrap(v.x, s.width));
            dmVoxelQuadric(dmMesoQuadrics[at], dmMesoQuadrics[at + 1], dmMesoQuadrics[at + 2], v.z, qa, qb, qc);
        }
        vec3 qo = vec3(float(v.x), float(v.y), 0.0);
        if (dmDdmStep(t, v, dist, qa, qb, qc, qo, o, d, exitRule, s.tol) == 1) {
            r.hit = true;
            break;
        }
    }
    r.t = t;
    return r;
}

// marchHeightSearch<float>: relief mapping (binary >= 0 bisections) or POM (binary < 0).
// View rays only (d.z < 0; the host checks), linear >= 1.
float dmMesoAbove(DmMesoSize s, vec3 o, vec3 d, float t, inout int iterations) {
    vec3 p = o + d * t;
    vec2 f;
    ivec2 c = dmHeightCell(vec2(p.x, p.y), f);
    ++iterations;
    return dmHeightAbove(p, dmMesoCell(s, c.x, c.y), f);
}

DmMesoHit dmMarchHeightSearch(DmMesoSize s, vec3 o, vec3 d, int linear, int binary) {
    DmMesoHit r;
    r.hit = false;
    r.iterations = 0;
    float tEnd = dmPlaneHit(o, d, 0.0);
    float dt = tEnd / float(linear);
    vec2 bracket = vec2(0.0, dt);
    float abovePrev = binary < 0 ? dmMesoAbove(s, o, d, 0.0, r.iterations) : 0.0;
    float aboveCur = 0.0;
    for (int i = 0; i < linear; ++i) {
        aboveCur = dmMesoAbove(s, o, d, bracket.y, r.iterations);
        float keep = aboveCur;
        if (dmLinearSearchStep(bracket, dt, aboveCur)) {
            break;
        }
        abovePrev = keep;
    }
    r.hit = true;
    if (binary < 0) {
        r.t = dmPomIntersect(bracket, abovePrev, aboveCur);
        return r;
    }
    for (int j = 0; j < binary; ++j) {
        bracket = dmBisectStep(bracket, dmMesoAbove(s, o, d, 0.5 * (bracket.x + bracket.y), r.iterations));
    }
    r.t = 0.5 * (bracket.x + bracket.y);
    return r;
}

#endif // DISPMAP_MESO_MARCH_GLSL
