// Writes its push constants and specialisation constant 1 to the output buffer, so that a test
// can check that both reach the shader.
#version 450
layout(local_size_x = 1) in;
layout(constant_id = 1) const uint kSpec = 7u;
layout(push_constant) uniform Push { uint a; float b; int c; } pc;
layout(std430, binding = 0) writeonly buffer Outputs { uint words[]; };

void main() {
    words[0] = pc.a;
    words[1] = floatBitsToUint(pc.b);
    words[2] = uint(pc.c);
    words[3] = kSpec;
}
