#version 450
// One patch per Ptex face: the vertex is the face id, read from the draw's face list.
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"
layout(location = 0) flat out int vFace;
void main() {
    vFace = int(drawFaces[gl_VertexIndex]);
}
