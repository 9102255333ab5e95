// The mesostructure marchers on the GPU: the memory of the loops that kernels/meso_march.h
// writes once for the CPU and the GPU (generated into meso_march.glsl). Only buffer reads
// live here; with NoContraction on the float operations (backend_vulkan/tools/spirv_exact.cpp)
// lavapipe gives the hits, parameters and iteration counts of include/dispmap/meso/march.h
// bit for bit.
//
// The includer defines DM_MESO_SET and DM_MESO_BINDING (the first of five consecutive
// storage-buffer bindings) before including this file, and fills a DmMesoSize from the host
// (backend_vulkan: mesoSize()). The buffers, std430, as the host maps hold them:
//   +0 heights    MesoHeightField::h, W x H floats, x fastest
//   +1 distances  DistanceMap::d, [k][j][i] floats
//   +2 grid       CompressedDdm::grid, [cone][bz][by][bx] uint words
//   +3 atlas      CompressedDdm::atlas, blocks of block^3 floats, x fastest, then
//                 CompressedDdm::planes (four floats a plane block)
//   +4 quadrics   ColumnQuadrics::q, three vec4 per column, x fastest
//   (+5 images    the albedo's and the normal map's MesoAlbedo::words: DM_MESO_IMAGE_BINDING below)
//   (+6 lists     a solid's PackedSolid::lists: each voxel's entry range, then the entries' words:
//                 DM_MESO_SOLID_BINDING)
//   (+7 triangles a solid's PackedSolid::triangles: three uvec4 a triangle, xyz the float bits of
//                 MesoSolid::triangleRow, w one corner's unit normal (octahedral, two snorm16))
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
// The images over a tile (MesoAlbedo::words, meso/albedo.h, one after the other: each read
// from its first word on), read only by dmMesoImage: binding DM_MESO_IMAGE_BINDING (default
// the sixth, DM_MESO_BINDING + 5).
#ifndef DM_MESO_IMAGE_BINDING
#define DM_MESO_IMAGE_BINDING (DM_MESO_BINDING + 5)
#endif
layout(std430, set = DM_MESO_SET, binding = DM_MESO_IMAGE_BINDING) readonly buffer DmMesoImageWords { uint dmMesoImageWords[]; };
// A non-height-field solid's triangle lists (meso/solid.h), read only by dmMarchDdmSolid and
// dmMesoSolidNormal: bindings DM_MESO_SOLID_BINDING (default DM_MESO_BINDING + 6) and one more.
#ifndef DM_MESO_SOLID_BINDING
#define DM_MESO_SOLID_BINDING (DM_MESO_BINDING + 6)
#endif
layout(std430, set = DM_MESO_SET, binding = DM_MESO_SOLID_BINDING) readonly buffer DmMesoSolidLists { uint dmMesoSolidLists[]; };
layout(std430, set = DM_MESO_SET, binding = DM_MESO_SOLID_BINDING + 1) readonly buffer DmMesoSolidTriangles { uvec4 dmMesoSolidTriangles[]; };

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
    int kind = 0;
    int b = s.block;
    float d = dmGridWordDistance(dmMesoGrid[((c * s.gz + k / b) * s.gy + j / b) * s.gx + i / b], atlasIndex, kind);
    if (kind == 0) {
        return d;
    }
    if (kind == 2) {
        return dmPlaneBlockDistance(dmMesoAtlas[atlasIndex], dmMesoAtlas[atlasIndex + 1], dmMesoAtlas[atlasIndex + 2], dmMesoAtlas[atlasIndex + 3],
                                    ivec3(i % b, j % b, k % b));
    }
    return dmMesoAtlas[atlasIndex * (b * b * b) + ((k % b) * b + j % b) * b + i % b];
}

// The includer's side of kernels/meso_march.h (the loops, generated into meso_march.glsl):
// the maps are the buffers above, named by their sizes.
#define DmMesoMaps DmMesoSize
float dmMesoFetchDistance(DmMesoSize s, int i, int j, int k) {
    return dmMesoDistanceAt(s, i, j, k);
}
float dmMesoFetchDdm(DmMesoSize s, int c, int i, int j, int k) {
    return dmMesoDdmLookup(s, c, i, j, k);
}
vec4 dmMesoFetchCell(DmMesoSize s, int i, int j) {
    return dmMesoCell(s, i, j);
}
vec4 dmMesoFetchQuadric(DmMesoSize s, int i, int j, int part) {
    return dmMesoQuadrics[3 * (dmMesoWrap(j, s.height) * s.width + dmMesoWrap(i, s.width)) + part];
}
uint dmMesoFetchImage(DmMesoSize s, int i) {
    return dmMesoImageWords[i];
}
ivec2 dmMesoFetchSolidRange(DmMesoSize s, int i, int j, int k) {
    int v = (k * s.height + dmMesoWrap(j, s.height)) * s.width + dmMesoWrap(i, s.width);
    return ivec2(int(dmMesoSolidLists[v]), int(dmMesoSolidLists[v + 1]));
}
uint dmMesoFetchSolidEntry(DmMesoSize s, int e) {
    return dmMesoSolidLists[e];
}
vec4 dmMesoFetchSolidTriangle(DmMesoSize s, int t, int part) {
    return vec4(uintBitsToFloat(dmMesoSolidTriangles[3 * t + part].xyz), 0.0);
}
#include "meso_march.glsl"
#undef DmMesoMaps

// The marchers as the stage shaders call them (meso.frag, parity_meso.comp).
DmMesoHit dmMarchDistanceMap(DmMesoSize s, vec3 o, vec3 d, int iterations, float eps) {
    DmMesoHit r;
    r.hit = dmMesoMarchDistance(s, o, d, iterations, eps, r.t, r.iterations);
    return r;
}
// The same along the ray bent by the base's curvature (bend: dmShellBend; curve: the most convex
// curvature in voxels, dmShellVoxels' w); p: the hit in the slab's coordinates (t is the
// straight ray's).
DmMesoHit dmMarchDistanceMapBent(DmMesoSize s, vec3 o, vec3 d, float bend, float curve, int iterations, float eps, out vec3 p) {
    DmMesoHit r;
    r.hit = dmMesoMarchDistanceBent(s, o, d, bend, curve, iterations, eps, r.t, p, r.iterations);
    return r;
}
DmMesoHit dmMarchDdm(DmMesoSize s, vec3 o, vec3 d, int maxIterations, bool quadrics, int exitRule) {
    DmMesoHit r;
    r.hit = dmMesoMarchDdm(s, o, d, s.coneM, s.coneN, maxIterations, quadrics, exitRule, s.tol, 3.0e38, r.t, r.iterations);
    return r;
}
// A solid's march (DDM with the triangles of its 0 voxels); triangle and uv: the triangle hit.
struct DmMesoSolidHit {
    DmMesoHit h;
    int triangle;
    vec2 uv;
};
// The DDM march along the ray bent by the base's curvature (bend, curve: as above), a height
// field's (quadrics or not) or with `solid` a solid's; p: the hit in the slab's coordinates (t
// is the straight ray's); triangle and uv: the solid's triangle hit (-1 otherwise).
DmMesoSolidHit dmMarchDdmBent(DmMesoSize s, vec3 o, vec3 d, float bend, float curve, int maxIterations, bool quadrics, bool solid,
                              int exitRule, float chordError, out vec3 p) {
    DmMesoSolidHit r;
    r.h.hit = dmMesoMarchDdmBent(s, o, d, bend, curve, s.coneM, s.coneN, maxIterations, quadrics, solid, exitRule, s.tol, chordError, r.h.t, p,
                                 r.h.iterations, r.triangle, r.uv);
    return r;
}
DmMesoSolidHit dmMarchDdmSolid(DmMesoSize s, vec3 o, vec3 d, int maxIterations, int exitRule) {
    DmMesoSolidHit r;
    r.h.hit = dmMesoMarchDdmSolid(s, o, d, s.coneM, s.coneN, maxIterations, exitRule, s.tol, 3.0e38, r.h.t, r.h.iterations, r.triangle, r.uv);
    return r;
}
// The voxel-space shading normal at a solid hit: the corners' normals (the rows' w) mixed by the
// barycentric uv (kern::dmSolidCornerNormal).
vec3 dmMesoSolidNormal(int triangle, vec2 uv) {
    return dmSolidCornerNormal(dmMesoSolidTriangles[3 * triangle].w, dmMesoSolidTriangles[3 * triangle + 1].w,
                               dmMesoSolidTriangles[3 * triangle + 2].w, uv);
}
// The geometric normal of the solid's triangle, facing the ray d; n (the shading normal) turned
// to its side (kern::dmSolidFacing).
vec3 dmMesoSolidFacing(DmMesoSize s, int triangle, vec3 d, inout vec3 n) {
    return dmSolidFacing(dmMesoFetchSolidTriangle(s, triangle, 1).xyz, dmMesoFetchSolidTriangle(s, triangle, 2).xyz, d, n);
}
// Relief mapping (binary >= 0 bisections) or POM (binary < 0); view rays only (d.z < 0; the
// host checks), linear >= 1.
DmMesoHit dmMarchHeightSearch(DmMesoSize s, vec3 o, vec3 d, int linear, int binary) {
    DmMesoHit r;
    r.hit = dmMesoMarchHeight(s, o, d, linear, binary, r.t, r.iterations);
    return r;
}
// The same along the ray bent by the base's curvature (bend, curve: as above); p: the hit in
// the slab's coordinates (t is the straight ray's).
DmMesoHit dmMarchHeightSearchBent(DmMesoSize s, vec3 o, vec3 d, float bend, float curve, int linear, int binary, out vec3 p) {
    DmMesoHit r;
    r.hit = dmMesoMarchHeightBent(s, o, d, bend, curve, linear, binary, r.t, p, r.iterations);
    return r;
}

#endif // DISPMAP_MESO_MARCH_GLSL
