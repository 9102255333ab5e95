// The main of the GPU tests: creates the shared Vulkan context first and exits 77 (skipped) when
// there is no loader, device or validation layer, or 1 with DISPMAP_REQUIRE_GPU=1. Validation
// messages that a test case did not check are collected per test case and fail the run.
// Catch2's implementation is tests/catch_impl.cpp.
#include <cstdio>
#include <memory>

#include "../catch_run.h"
#include "gpu_support.h"

namespace {

std::unique_ptr<dispmap::vulkan::Context>& sharedContext() {
    static std::unique_ptr<dispmap::vulkan::Context> context;
    return context;
}

/// "<test case>: <message>" for every validation message left over at the end of a test case.
std::vector<std::string>& leftoverMessages() {
    static std::vector<std::string> messages;
    return messages;
}

void collectLeftovers(const std::string& where) {
    if (!sharedContext()) return;
    for (const std::string& m : sharedContext()->takeValidationMessages())
        leftoverMessages().push_back(where + ": " + m);
}

struct ValidationListener : Catch::TestEventListenerBase {
    using TestEventListenerBase::TestEventListenerBase;
    void testCaseEnded(const Catch::TestCaseStats& stats) override { collectLeftovers(stats.testInfo.name); }
};

} // namespace

CATCH_REGISTER_LISTENER(ValidationListener)

namespace dmgpu {
dispmap::vulkan::Context& context() {
    auto& context = sharedContext();
    if (!context) {
        context = std::make_unique<dispmap::vulkan::Context>(dispmap::vulkan::DeviceOptions{
            .validation = true, .float64 = dispmap::vulkan::Float64::IfSupported});
    }
    return *context;
}
} // namespace dmgpu

int main(int argc, char* argv[]) {
    int result = dmtest::runCatch(argc, argv, [](bool listing) {
        if (listing) return 0;
        try {
            const auto& ctx = dmgpu::context();
            std::printf("gpu tests on '%s' (validation %s, float64 %s, timestamps %s)\n",
                        ctx.deviceName().c_str(), ctx.validationEnabled() ? "on" : "off",
                        ctx.float64Enabled() ? "on" : "off", ctx.timestampsSupported() ? "on" : "off");
        } catch (const dispmap::Error& e) {
            const char* require = std::getenv("DISPMAP_REQUIRE_GPU");
            if (require && std::string(require) == "1") {
                std::printf("gpu tests failed (DISPMAP_REQUIRE_GPU=1): %s\n", e.what());
                return 1;
            }
            std::printf("gpu tests skipped: %s\n", e.what());
            return 77;
        }
        return 0;
    });
    collectLeftovers("after the tests");
    if (!leftoverMessages().empty()) {
        std::printf("%zu validation message(s) not checked by the tests:\n", leftoverMessages().size());
        for (const std::string& m : leftoverMessages())
            std::printf("  %s\n", m.c_str());
        if (result == 0) result = 1;
    }
    sharedContext().reset();
    return result;
}
