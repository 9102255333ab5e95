#version 450
// Your own compute shader sampling dispmap's packed displacement tiles with the installed GLSL
// includes (share/dispmap/glsl): one query (record, u, v, resolution) per invocation gives
// (D, D_u, D_v), the lookup the tessellation evaluation shader makes. docs/glsl.md lists the API.
#extension GL_GOOGLE_include_directive : require
#include "tile.glsl"
#include "lod.glsl"

layout(local_size_x = 64) in;
layout(push_constant) uniform Push {
    uint count;
    int width; // of the packed texture, in texels
} pc;

struct Query {
    vec2 uv;   // the tile's (u, v)
    float rho; // wanted resolution: log2 of the level size (64 = finest the tile has)
    int record;
};
// packed_tiles.glsl reads `texels` and `packedWidth()`; the includer declares both.
layout(std430, binding = 0) readonly buffer Texels { float texels[]; };
layout(std430, binding = 1) readonly buffer Records { uvec4 records[]; };
layout(std430, binding = 2) readonly buffer Queries { Query queries[]; };
layout(std430, binding = 3) writeonly buffer Results { vec4 results[]; };
int packedWidth() {
    return pc.width;
}
#include "packed_tiles.glsl"

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pc.count) {
        return;
    }
    Query q = queries[i];
    float weight;
    results[i] = vec4(packedSampleD1(records[q.record], q.uv, q.rho, weight), weight);
}
