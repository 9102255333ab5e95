#version 450
// The MesoRenderer's base mesh other than the plane (surface/frame_mesh.h): each corner's
// position and frame, pulled by the vertex index (three a triangle, no vertex buffer); the
// rasteriser interpolates the frame for meso.frag.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(location = 0) out vec3 worldPos;
layout(location = 1) out vec2 tex;
layout(location = 2) out vec3 framePS;
layout(location = 3) out vec3 framePT;
layout(location = 4) out vec3 frameN;
layout(location = 5) out vec4 frameShape;

void main() {
    DmFrameVertex v = frameVertices[gl_VertexIndex];
    worldPos = v.position.xyz;
    tex = vec2(v.position.w, v.pS.w);
    framePS = v.pS.xyz;
    framePT = v.pT.xyz;
    frameN = v.normal.xyz;
    frameShape = v.shape;
    gl_Position = params.viewProj * vec4(v.position.xyz, 1.0);
}
