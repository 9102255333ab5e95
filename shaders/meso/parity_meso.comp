#version 450
// CPU/GPU parity of the mesostructure marchers (shaders/meso/march.glsl against
// include/dispmap/meso/march.h): one ray per invocation through the method the push
// constants name; writes (hit, t bits, iterations, the solid's triangle hit + 1). Runner: backend_vulkan/parity/meso_parity.cpp.
#extension GL_GOOGLE_include_directive : require
#define DM_MESO_SET 0
#define DM_MESO_BINDING 0
#define DM_MESO_SOLID_BINDING 7  // a solid's entry starts and entries: 7 and 8
#define DM_MESO_IMAGE_BINDING 9  // declared by march.glsl, not read here (5 and 6 are the rays and results)
#include "march.glsl"

layout(local_size_x = 64) in;
layout(push_constant) uniform Push {
    int width;
    int height;
    int layers;
    int block;
    int gx;
    int gy;
    int gz;
    int coneM;
    int coneN;
    float tol;
    int method;    // 0 distance map, 1 DDM, 2 relief, 3 POM (MesoMethod's order), 4 the solid's DDM march, 5 the DDM along a bent ray (bend: o.w; eps: the chord error), 6 relief (binary >= 0) or POM (binary < 0) along a bent ray, 7 the solid's DDM along a bent ray, 8 the distance map along a bent ray
    int iterations;
    float eps;
    int quadrics;
    int exitRule;
    int linear;
    int binary;
    uint count;
    uint rowStride;
} pc;

struct Ray {
    vec4 o; // xyz; w: the bend (method 5)
    vec4 d; // xyz, unit; w: the curve (methods 5 to 8)
};
layout(std430, binding = 5) readonly buffer Rays { Ray rays[]; };
layout(std430, binding = 6) writeonly buffer Results { uvec4 results[]; };

void main() {
    uint i = gl_GlobalInvocationID.y * pc.rowStride + gl_GlobalInvocationID.x;
    if (i >= pc.count) {
        return;
    }
    DmMesoSize s;
    s.width = pc.width;
    s.height = pc.height;
    s.layers = pc.layers;
    s.block = pc.block;
    s.gx = pc.gx;
    s.gy = pc.gy;
    s.gz = pc.gz;
    s.coneM = pc.coneM;
    s.coneN = pc.coneN;
    s.tol = pc.tol;
    vec3 o = rays[i].o.xyz;
    vec3 d = rays[i].d.xyz;
    DmMesoHit h;
    int entry = -1;
    if (pc.method == 4) {
        DmMesoSolidHit sh = dmMarchDdmSolid(s, o, d, pc.iterations, pc.exitRule);
        h = sh.h;
        entry = sh.triangle;
    } else if (pc.method == 5 || pc.method == 7) {
        vec3 p;
        DmMesoSolidHit sh = dmMarchDdmBent(s, o, d, rays[i].o.w, rays[i].d.w, pc.iterations, pc.quadrics != 0, pc.method == 7, pc.exitRule, pc.eps, p);
        h = sh.h;
        entry = sh.triangle;
    } else if (pc.method == 8) {
        vec3 p;
        h = dmMarchDistanceMapBent(s, o, d, rays[i].o.w, rays[i].d.w, pc.iterations, pc.eps, p);
    } else if (pc.method == 6) {
        vec3 p;
        h = dmMarchHeightSearchBent(s, o, d, rays[i].o.w, rays[i].d.w, pc.linear, pc.binary, p);
    } else if (pc.method == 0) {
        h = dmMarchDistanceMap(s, o, d, pc.iterations, pc.eps);
    } else if (pc.method == 1) {
        h = dmMarchDdm(s, o, d, pc.iterations, pc.quadrics != 0, pc.exitRule);
    } else {
        h = dmMarchHeightSearch(s, o, d, pc.linear, pc.method == 3 ? -1 : pc.binary);
    }
    results[i] = uvec4(h.hit ? 1u : 0u, floatBitsToUint(h.t), uint(h.iterations), uint(entry + 1));
}
