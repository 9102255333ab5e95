#version 450
// CPU/GPU parity of the base-surface patch kernels (kernels/patch.h): runs kernel number
// `kernel` of the dispatch in parity_patch.h (generated to GLSL) on `count` inputs of
// (PatchParam, control-point count, face (u, v)). Compiled twice: float, and with
// PARITY_DOUBLE for the double variants (needs shaderFloat64).
#extension GL_GOOGLE_include_directive : require
#ifdef PARITY_DOUBLE
#define DM_ENABLE_DOUBLE
#endif
#include "parity_patch.glsl"

layout(local_size_x = 64) in;
layout(push_constant) uniform Push {
    int kernel;
    uint count;
    uint rowStride; // invocations per row of the dispatch grid (groups.x * 64)
} pc;

#ifdef PARITY_DOUBLE
#define preal double
#define pvec2 dvec2
#else
#define preal float
#define pvec2 vec2
#endif
layout(std430, binding = 0) readonly buffer Args { preal args[]; };        // u, v per input
layout(std430, binding = 1) readonly buffer IntArgs { ivec4 intArgs[]; };  // field0, field1, cvCount, 0
layout(std430, binding = 2) writeonly buffer Results { preal results[]; }; // 120 per input
layout(std430, binding = 3) writeonly buffer IntResults { ivec4 intResults[]; };

void main() {
    uint i = gl_GlobalInvocationID.y * pc.rowStride + gl_GlobalInvocationID.x;
    if (i >= pc.count) {
        return;
    }
    ivec4 n = intArgs[i];
    preal r[120];
    ivec4 o;
    dmParityPatch(pc.kernel, uvec2(uint(n.x), uint(n.y)), n.z, pvec2(args[2u * i], args[2u * i + 1u]), r, o);
    for (uint j = 0u; j < 120u; ++j) {
        results[120u * i + j] = r[j];
    }
    intResults[i] = o;
}
