#version 450
// The base mesh of the MesoRenderer: the plane z = 0, |x|, |y| <= half, as quads x quads quads
// (two triangles each) generated from the vertex index; no vertex buffer.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(location = 0) out vec3 worldPos;
// The frame of base.vert: meso.frag reads it only on a base mesh (kBase), the plane's is world space.
layout(location = 1) out vec2 tex;
layout(location = 2) out vec3 framePS;
layout(location = 3) out vec3 framePT;
layout(location = 4) out vec3 frameN;
layout(location = 5) out vec4 frameShape;

void main() {
    int quads = int(params.plane.y);
    int q = gl_VertexIndex / 6;
    int corner = gl_VertexIndex % 6; // (0,0) (1,0) (1,1) | (0,0) (1,1) (0,1)
    int cx = (corner == 1 || corner == 2 || corner == 4) ? 1 : 0;
    int cy = (corner == 2 || corner == 4 || corner == 5) ? 1 : 0;
    float step = 2.0 * params.plane.x / float(quads);
    vec3 p = vec3(-params.plane.x + float(q % quads + cx) * step, -params.plane.x + float(q / quads + cy) * step, 0.0);
    worldPos = p;
    tex = vec2(0.0);
    framePS = vec3(1.0, 0.0, 0.0);
    framePT = vec3(0.0, 1.0, 0.0);
    frameN = vec3(0.0, 0.0, 1.0);
    frameShape = vec4(0.0); // flat
    gl_Position = params.viewProj * vec4(p, 1.0);
}
