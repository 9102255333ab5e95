#version 450
// CPU/GPU parity: runs kernel number `kernel` of the parity dispatch (parity_tile.h,
// parity_lod.h, generated to GLSL) on `count` packed argument lists. Compiled twice: float,
// and with PARITY_DOUBLE for the double variants (needs shaderFloat64).
#extension GL_GOOGLE_include_directive : require
#ifdef PARITY_DOUBLE
#define DM_ENABLE_DOUBLE
#endif
#include "parity_tile.glsl"
#include "parity_lod.glsl"

layout(local_size_x = 64) in;
layout(push_constant) uniform Push {
    int kernel;
    uint count;
    uint rowStride; // invocations per row of the dispatch grid (groups.x * 64)
} pc;

#ifdef PARITY_DOUBLE
#define preal double
#define pvec4 dvec4
#else
#define preal float
#define pvec4 vec4
#endif
layout(std430, binding = 0) readonly buffer Args { preal args[]; };  // 12 per input
layout(std430, binding = 1) readonly buffer IntArgs { ivec4 intArgs[]; };
layout(std430, binding = 2) writeonly buffer Results { preal results[]; }; // 12 per input
layout(std430, binding = 3) writeonly buffer IntResults { ivec4 intResults[]; };

pvec4 load4(uint at) {
    return pvec4(args[at], args[at + 1u], args[at + 2u], args[at + 3u]);
}
void store4(uint at, pvec4 v) {
    results[at] = v.x;
    results[at + 1u] = v.y;
    results[at + 2u] = v.z;
    results[at + 3u] = v.w;
}

void main() {
    uint i = gl_GlobalInvocationID.y * pc.rowStride + gl_GlobalInvocationID.x;
    if (i >= pc.count) {
        return;
    }
    pvec4 a = load4(12u * i);
    pvec4 b = load4(12u * i + 4u);
    pvec4 c = load4(12u * i + 8u);
    ivec4 n = intArgs[i];
    pvec4 r;
    pvec4 q;
    pvec4 p;
    ivec4 o;
    if (pc.kernel < 32) {
        dmParityTile(pc.kernel, a, b, c, n, r, q, p, o);
    } else {
#ifdef PARITY_DOUBLE
        r = pvec4(0);
        o = ivec4(0);
#else
        dmParityLod(pc.kernel, a, b, n, r, o);
#endif
        q = pvec4(0);
        p = pvec4(0);
    }
    store4(12u * i, r);
    store4(12u * i + 4u, q);
    store4(12u * i + 8u, p);
    intResults[i] = o;
}
