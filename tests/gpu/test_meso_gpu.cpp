// The mesostructure marchers on the GPU (shaders/meso/march.glsl) against the CPU marchers
// (include/dispmap/meso_march.h): bit parity of hit, t and iteration count for every method on
// lavapipe; the MesoRenderer against the CPU marchers on its own pixel rays.
#include <algorithm>
#include <chrono>
#include <string>

#include "gpu_support.h"
#include "meso_parity.h"

TEST_CASE("every mesostructure marcher agrees bit for bit between C++ and the compute shader", "[meso]") {
    auto& ctx = dmgpu::context();
    dispmap::parity::Options opt;
    opt.mesoRays = 2048; // 10 ray kinds x ~200; a few seconds under AddressSanitizer
    opt.filter = "march ";
    const bool strict = dispmap::parity::strictFor(ctx, opt);
    INFO("device " << ctx.deviceName() << (strict ? " (strict: no FMA contraction)" : ""));
    const auto results = dispmap::parity::runMeso(ctx, opt);
    REQUIRE(results.size() == 12);
    for (const auto& r : results) {
        INFO(r.kernel << ": " << r.bitExact << " of " << r.inputs << " bit-exact, max " << r.maxUlp << " ULP, worst " << r.worstInput);
        CHECK(r.inputs == 2048);
        CHECK(r.ok());
        // Lavapipe does not contract multiply-adds and rounds sqrt and division correctly
        // (measured): the GPU loop takes every decision the CPU takes.
        if (strict) CHECK(r.bitExact == r.inputs);
    }
    dmgpu::checkNoValidationMessages();
}
