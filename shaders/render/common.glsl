// The tessellation renderer's shared declarations: specialisation constants (the effects a
// scene asks for), the descriptor bindings and the small gathers between kernel calls. Every
// formula lives in the generated kernels; what is here only fetches data and calls them.
// Layouts mirror the Gpu* structs of backend_vulkan/src/renderer.cpp (static_asserts there).
#include "prelude.glsl"
#include "sum.glsl"
#include "bspline.glsl"
#include "tile.glsl"
#include "lod.glsl"
#include "normal.glsl"
#include "patch.glsl"
#include "baseline.glsl"
#include "sharp.glsl"

// Effects (specialisation constants; code of an effect that is off is removed when the
// pipeline is created). DM_LEAN builds the shaders without the optional effects at all, for
// the benchmark that shows "off" costs what "not built" costs.
layout(constant_id = 0) const int TECHNIQUE = 1;  // 0 base surface, 1 displaced (ours), 2 baseline
layout(constant_id = 1) const int NORMALS = 0;    // 0 approximate, 1 accurate, 2 auto (per face)
layout(constant_id = 2) const int LOD = 1;        // 0 off, 1 log2 TF (§6.2), 2 the texel-ratio rule
layout(constant_id = 3) const int TESS_METHOD = 0; // 0 uniform, 1 distance, 2 screen edge, 3 screen area
layout(constant_id = 4) const bool CAPTURE = false; // TES writes its vertices (tests)
layout(constant_id = 5) const bool WIRE = false;    // wireframe overlay pass
layout(constant_id = 6) const bool TEXELS_HALF = false;  // tile texels as half floats (TexelFormat::Half)
layout(constant_id = 7) const bool TEXELS_IMAGE = false; // tile texels from a sampled image (texelFetch), not a buffer
layout(constant_id = 8) const bool BASELINE_UV = false;  // the baseline in the mesh's UV layout (BaselineLayout::MeshUv)
#ifdef DM_LEAN
#define HAS_ACCURATE false
#define HAS_LOD false
#define HAS_CAPTURE false
#else
#define HAS_ACCURATE (NORMALS != 0)
#define HAS_LOD (LOD != 0)
#define HAS_CAPTURE CAPTURE
#endif

#define DM_LEAF 0x80000000u

struct Light {
    vec4 direction; // towards the light
    vec4 color;
};
layout(std430, set = 0, binding = 0) readonly buffer Params {
    mat4 viewProj;
    vec4 eye;       // xyz
    vec4 viewport;  // width, height (pixels), sharp features' cap radius (DisplacedSurface::sharpCapRadius), 0
    vec4 tess;      // factor value or constant c, max factor, sharp-feature band, 1: end-cap normals (§5.4)
    vec4 albedo;    // rgb, ambient
    vec4 wireColor;
    vec4 atlas;     // baseline atlas width, height, texels per face edge (faces layout), 0
    ivec4 counts;   // light count, capture capacity, packed tile texture width, 0
    Light lights[8]; // kMaxLights (surface/draw.h)
} P;
layout(std430, set = 0, binding = 1) readonly buffer Points { vec4 points[]; };
layout(std430, set = 0, binding = 2) readonly buffer PatchIndices { uint patchIndices[]; };
layout(std430, set = 0, binding = 3) readonly buffer Patches { uvec4 patches[]; };
layout(std430, set = 0, binding = 4) readonly buffer Nodes { uvec4 nodes[]; };
layout(std430, set = 0, binding = 5) readonly buffer FaceRoots { uint faceRoots[]; };
layout(std430, set = 0, binding = 6) readonly buffer CornerNormals { vec4 cornerNormals[]; };
// The packed tiles' texels: float bits, or two half floats a word (low half first).
layout(std430, set = 0, binding = 7) readonly buffer Texels { uint texelWords[]; };
// The displaced technique's patch records; for the mesh-UV baseline (BASELINE_UV), 6 a face
// holding float bits: corner UVs (c0, c1), (c2, c3), then the per-vertex tangents at the four
// corners (xyz). One binding for the two techniques' per-face data keeps the set at 16 storage
// buffers.
layout(std430, set = 0, binding = 8) readonly buffer Records { uvec4 records[]; };
struct Face {
    uvec4 corners; // TileTopology vertex ids of the corners (0 (0,0), 1 (1,0), 2 (1,1), 3 (0,1))
    ivec4 info;    // x: 1 for a sub-face of an N-gon, y: auto mode's accurate flag, z: T-junction edge bits,
                   // w: sharp-feature mask (BaseSurface::sharpMask; 0 with the band off)
    uvec4 chart;   // baseline atlas chart origin (x, y), 0, 0
};
layout(std430, set = 0, binding = 9) readonly buffer Faces { Face faces[]; };
struct BaseVertex {
    vec4 position; // limit position, w: the mip floor (base resolution: 1, or 2 at non-quad faces)
    ivec4 ring;    // one-ring offset and count in ringIndices, kMin (texel-ratio rule), 1 if the ring is closed
};
layout(std430, set = 0, binding = 10) readonly buffer BaseVertices { BaseVertex baseVertices[]; };
layout(std430, set = 0, binding = 11) readonly buffer RingIndices { uint ringIndices[]; };
layout(std430, set = 0, binding = 12) readonly buffer TileVertices { uvec2 tileVertices[]; }; // spread offset, count
layout(std430, set = 0, binding = 13) readonly buffer SpreadIndices { uint spreadIndices[]; };
layout(std430, set = 0, binding = 14) readonly buffer DrawFaces { uint drawFaces[]; };
struct Captured {
    vec4 position; // xyz, w: rho
    vec4 faceUV;   // face (as float), u, v, 0
};
layout(std430, set = 0, binding = 15) buffer Capture {
    uint captureCount;
    uint capturePad0;
    uint capturePad1;
    uint capturePad2;
    Captured captured[];
};
layout(set = 0, binding = 16) uniform sampler2D baselineHeight;
layout(set = 0, binding = 17) uniform sampler2D baselineNormal;
layout(set = 0, binding = 18) uniform sampler2D packedImage; // the packed tiles (R32F or R16F) with TEXELS_IMAGE

int packedWidth() {
    return P.counts.z;
}
// Texel (x, y) of the packed tiles, from wherever the effects put them. Every path returns the
// stored value exactly (half to float conversion is exact), so all four agree bit for bit
// with the CPU's PackedTiles::sampleD1 on the same texels.
float packedTexel(int x, int y) {
    if (TEXELS_IMAGE) {
        return texelFetch(packedImage, ivec2(x, y), 0).r;
    }
    int i = y * packedWidth() + x;
    if (TEXELS_HALF) {
        return unpackHalf2x16(texelWords[i >> 1])[i & 1];
    }
    return uintBitsToFloat(texelWords[i]);
}
#define DM_PACKED_TEXEL(x, y) packedTexel(x, y)
#include "../packed_tiles.glsl"

// (D, D_u, D_v) at face (u, v) read at resolution rho (the tile records are per Ptex face),
// faded towards sharp features (DisplacedSurface::featheredAt).
vec3 sampleD1(int face, vec2 uv, float rho) {
    float weight;
    vec3 d1 = packedSampleD1(records[face], uv, rho, weight);
    return dmSharpFeather(uv, faces[face].info.w, faces[face].info.x, P.tess.z, P.viewport.z, d1);
}

// The patch record holding face (u, v): down the face's quadtree (PackedSurface).
uvec4 findPatch(int face, vec2 uv) {
    uint node = faceRoots[face];
    vec2 q = uv;
    while ((node & DM_LEAF) == 0u) {
        int c = dmQuadTreeStep(q);
        node = nodes[node][c];
    }
    return patches[node & ~DM_LEAF];
}

// s and its derivatives (second ones included) of the patch `patchRec` at face (u, v).
void evaluatePatch2(uvec4 patchRec, vec2 uv, out vec3 p, out vec3 su, out vec3 sv, out vec3 suu, out vec3 suv, out vec3 svv) {
    float w[20];
    float wu[20];
    float wv[20];
    float wuu[20];
    float wuv[20];
    float wvv[20];
    int count = int(patchRec.y);
    dmPatchBasis2(patchRec.zw, count, uv, w, wu, wv, wuu, wuv, wvv);
    p = vec3(0.0);
    su = vec3(0.0);
    sv = vec3(0.0);
    suu = vec3(0.0);
    suv = vec3(0.0);
    svv = vec3(0.0);
    for (int i = 0; i < count; ++i) {
        vec3 x = points[patchIndices[patchRec.x + uint(i)]].xyz;
        p += w[i] * x;
        su += wu[i] * x;
        sv += wv[i] * x;
        suu += wuu[i] * x;
        suv += wuv[i] * x;
        svv += wvv[i] * x;
    }
}

// §5.4 (DisplacedSurface::endCapNormal): where an end-cap patch at an extraordinary corner
// holds face (u, v), the normal interpolated from the displaced normals at the patch's corners
// (each evaluated in the patch beyond it) and the limit normal at the extraordinary corner,
// blended back to `n` (the pixel's own displaced normal) towards the patch's outer edges;
// elsewhere `n`. Decided per pixel from the pixel's own patch, as the CPU decides per point.
vec3 endCapNormal(int face, vec2 uv, float rho, bool accurate, vec3 n) {
    uvec4 patchRec = findPatch(face, uv);
    if (dmPatchRegular(patchRec.zw)) {
        return n;
    }
    int last = (1 << dmPatchDomainLevel(patchRec.zw)) - 1;
    ivec2 offset = dmPatchOffset(patchRec.zw);
    float size = 1.0 / float(1 << dmPatchDomainLevel(patchRec.zw));
    vec2 origin = vec2(offset) * size;
    vec2 centre = origin + vec2(0.5 * size);
    int evCorner = -1;
    vec3 nc[4];
    for (int c = 3; c >= 0; --c) {
        vec2 corner = vec2((c == 1 || c == 2) ? 1.0 : 0.0, c >= 2 ? 1.0 : 0.0);
        bool touches = (c == 1 || c == 2 ? offset.x == last : offset.x == 0) && (c >= 2 ? offset.y == last : offset.y == 0);
        vec2 cuv = origin + corner * size;
        vec4 cn = cornerNormals[face * 4 + c];
        if (cn.w != 0.0 && touches) {
            nc[c] = cn.xyz;
            evCorner = c;
        } else {
            vec3 p;
            vec3 su;
            vec3 sv;
            vec3 suu;
            vec3 suv;
            vec3 svv;
            // In the patch beyond the corner (BaseSurface::endCapCorners: regular there).
            evaluatePatch2(findPatch(face, clamp(2.0 * cuv - centre, vec2(0.0), vec2(1.0))), cuv, p, su, sv, suu, suv, svv);
            vec3 N = dmBaseNormal(su, sv, suu, suv, svv, cuv, vec3(0.0, 0.0, 1.0));
            vec3 d1 = sampleD1(face, cuv, rho);
            vec3 fu;
            vec3 fv;
            if (accurate) {
                vec3 Nu;
                vec3 Nv;
                dmNormalDerivWeingarten(su, sv, suu, suv, svv, N, 1e-3, Nu, Nv);
                nc[c] = dmDisplacedNormalAccurate(su, sv, N, Nu, Nv, d1, fu, fv);
            } else {
                nc[c] = dmDisplacedNormalApprox(su, sv, N, d1, fu, fv);
            }
        }
    }
    if (evCorner < 0) {
        return n; // an end cap at a feature other than an extraordinary vertex (a dart, a corner)
    }
    return dmEndCapNormal(nc[0], nc[1], nc[2], nc[3], dmPatchLocal(patchRec.zw, uv), n, evCorner);
}

// The baseline's texture coordinate of face (u, v): in the face's chart, or at its mesh UV
// (baselineTexcoord of include/dispmap/surface/baseline.h).
vec2 baselineUV(int face, vec2 uv) {
    if (BASELINE_UV) {
        vec2 du;
        vec2 dv;
        return dmUvTexcoord(dmFaceUv(uintBitsToFloat(records[6 * face]), uintBitsToFloat(records[6 * face + 1]), uv, du, dv));
    }
    return dmBaselineAtlasUV(vec2(faces[face].chart.xy), uv, P.atlas.z, P.atlas.xy);
}

// The tangent the baseline's normal map is stored in at face (u, v) (baselineTangent).
vec3 baselineTangent(int face, vec2 uv, vec3 su, vec3 N) {
    if (BASELINE_UV) {
        int i = 6 * face + 2;
        return dmFaceTangent(uintBitsToFloat(records[i].xyz), uintBitsToFloat(records[i + 1].xyz), uintBitsToFloat(records[i + 2].xyz),
                             uintBitsToFloat(records[i + 3].xyz), uv, N);
    }
    return dmTangentFromDerivative(su, N);
}
