#pragma once
// Shared helpers of the GPU tests: the process-wide Vulkan context, the validation check that
// ends every test case, and a guard that sets an environment variable for a scope.
#include <cstdlib>
#include <string>
#include <vector>

#include <catch2/catch.hpp>

#include "dispmap/vulkan/buffer.h"
#include "dispmap/vulkan/compute.h"
#include "dispmap/vulkan/context.h"
#include "parity.h"

namespace dmgpu {

/// The one Context of the test process: validation on, shaderFloat64 enabled where supported.
/// Created on first use (the main creates it before any test, to decide whether to skip).
dispmap::vulkan::Context& context();

/// Whether the device rounds every operation as the C++ side does (lavapipe, measured): then the
/// tests hold GPU results to the CPU's bit for bit, else to what Vulkan allows a device
/// (dispmap::parity::strictFor; docs/figures.md has what an NVIDIA H200 gave).
inline bool strict() { return dispmap::parity::strictFor(context(), dispmap::parity::Options{}); }

/// CHECKs that the validation layer reported nothing since the last call; prints what it did report.
inline void checkNoValidationMessages() {
    const std::vector<std::string> messages = context().takeValidationMessages();
    for (const std::string& m : messages)
        UNSCOPED_INFO(m);
    CHECK(messages.empty());
}

/// Sets (value != nullptr) or unsets an environment variable; restores the previous state on exit.
class EnvGuard {
  public:
    EnvGuard(const char* name, const char* value) : name_(name) {
        if (const char* old = std::getenv(name)) {
            had_ = true;
            old_ = old;
        }
        if (value)
            setenv(name, value, 1);
        else
            unsetenv(name);
    }
    ~EnvGuard() {
        if (had_)
            setenv(name_.c_str(), old_.c_str(), 1);
        else
            unsetenv(name_.c_str());
    }
    EnvGuard(const EnvGuard&) = delete;
    EnvGuard& operator=(const EnvGuard&) = delete;

  private:
    std::string name_, old_;
    bool had_ = false;
};

} // namespace dmgpu
