// Bit-parity smoke test of the backend (docs/lavapipe.md): y = sqrt(|p(x)|) / (1 + x^2) with p
// a degree-5 polynomial in Horner form, in float, or in double with -DDM_DOUBLE.
// test_vulkan_backend.cpp evaluates the same expression in C++ and expects 0 ULP difference on
// lavapipe. `precise`: no fused multiply-adds (the C++ side is built with -ffp-contract=off);
// near the roots of p a fused Horner step moved y by up to 955561 ULP on an NVIDIA H200.
#version 450
#ifdef DM_DOUBLE
#define real double
const double c0 = 0.3lf, c1 = -1.7lf, c2 = 0.45lf, c3 = 2.1lf, c4 = -0.65lf, c5 = 0.11lf, one = 1.0lf;
#else
#define real float
const float c0 = 0.3, c1 = -1.7, c2 = 0.45, c3 = 2.1, c4 = -0.65, c5 = 0.11, one = 1.0;
#endif

layout(local_size_x_id = 0) in; // specialisation constant 0: the work group size
layout(push_constant) uniform Push { uint count; } pc;
layout(std430, binding = 0) readonly buffer Inputs { real xs[]; };
layout(std430, binding = 1) writeonly buffer Outputs { real ys[]; };

void main() {
    const uint i = gl_GlobalInvocationID.x;
    if (i >= pc.count) return;
    const real x = xs[i];
    precise real p = ((((c5 * x + c4) * x + c3) * x + c2) * x + c1) * x + c0;
    precise real y = sqrt(abs(p)) / (one + x * x);
    ys[i] = y;
}
