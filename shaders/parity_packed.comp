#version 450
// CPU/GPU parity of the whole displacement lookup of the renderer: patch (u, v) -> tile
// (u, v) (dmPatchToTile) -> §4.4 maximum resolution -> mip selection -> two packed 3 x 3
// blocks -> (D, D_u, D_v) -> blend. The C++ twin is PackedTiles::sampleD1 (tileset.h); the
// steps between the kernel calls are the texel gather and nothing else.
#extension GL_GOOGLE_include_directive : require
#include "tile.glsl"
#include "lod.glsl"

layout(local_size_x = 64) in;
layout(push_constant) uniform Push {
    uint count;
    uint rowStride;
    int width; // of the packed texture, in texels
} pc;

struct Query {
    vec2 uv;     // patch (u, v)
    float rho;   // wanted resolution (log2 of the level size)
    int record;
    int depth;   // patch depth below the tile (dmPatchToTile)
    int pad0;
    int pad1;
    int pad2;
};
layout(std430, binding = 0) readonly buffer Texels { float texels[]; };
layout(std430, binding = 1) readonly buffer Records { uvec4 records[]; };
layout(std430, binding = 2) readonly buffer Queries { Query queries[]; };
layout(std430, binding = 3) writeonly buffer Results { vec4 results[]; };

int packedWidth() {
    return pc.width;
}
#include "packed_tiles.glsl"

void main() {
    uint i = gl_GlobalInvocationID.y * pc.rowStride + gl_GlobalInvocationID.x;
    if (i >= pc.count) {
        return;
    }
    Query qy = queries[i];
    uvec4 r = records[qy.record];
    vec2 uv = dmPatchToTile(qy.uv, dmRecordLocalOffset(r), qy.depth, dmRecordRotation(r));
    float w;
    vec3 d1 = packedSampleD1(r, uv, qy.rho, w);
    results[i] = vec4(d1, w);
}
