// CPU/GPU parity of every kernel under its precision contract (backend_vulkan/parity): the
// exhaustive input sets of `dispmap parity`, run on the test device with validation on.
#include <string>

#include "gpu_support.h"
#include "parity.h"

TEST_CASE("every kernel agrees between C++ and the compute shader within its contract", "[parity]") {
    auto& ctx = dmgpu::context();
    dispmap::parity::Options opt; // the default input sets: ~12 M inputs, a few seconds on lavapipe
    const bool strict = dispmap::parity::strictFor(ctx, opt);
    INFO("device " << ctx.deviceName() << (strict ? " (strict: no FMA contraction)" : ""));
    const auto results = dispmap::parity::run(ctx, opt);
    std::size_t kernels = 0, doubles = 0, patchKernels = 0;
    for (const auto& r : results) {
        INFO(r.kernel << " (" << r.precision << "): max " << r.maxUlp << " " << r.unit << ", bound " << r.bound
                      << ", worst input " << r.worstInput);
        CHECK(r.inputs >= 120); // the smallest set: every k = 1..15 with every level
        CHECK(r.ok());
        // The contract on a device that does not contract multiply-adds (lavapipe, measured):
        // the exact kernels match bit for bit on every input, not just within 0.5 ULP.
        if (strict && r.contract == "exact") CHECK(r.bitExact == r.inputs);
        ++kernels;
        doubles += r.precision == "double" ? 1u : 0u;
        // The base-surface patch kernels (kernels/patch.h) on real Far PatchParams.
        for (const char* name : {"dmPatchBasis2 (B-spline)", "dmPatchBasis2 (Gregory)", "dmPatchBasis1", "dmQuadTreeStep",
                                 "dmPatchLocal+dmEndCapCornerWeights"})
            patchKernels += r.kernel == name ? 1u : 0u;
    }
    CHECK(patchKernels == (ctx.float64Enabled() ? 10u : 5u));
    CHECK(kernels >= 30);
    if (ctx.float64Enabled()) CHECK(doubles >= 19);
    dmgpu::checkNoValidationMessages();
}

TEST_CASE("a kernel filter runs only the named kernels", "[parity]") {
    auto& ctx = dmgpu::context();
    dispmap::parity::Options opt;
    opt.inputs = 4096;
    opt.filter = "dmBiquadraticD1";
    const auto results = dispmap::parity::run(ctx, opt);
    REQUIRE_FALSE(results.empty());
    for (const auto& r : results) CHECK(r.kernel == "dmBiquadraticD1");
    dmgpu::checkNoValidationMessages();
}
