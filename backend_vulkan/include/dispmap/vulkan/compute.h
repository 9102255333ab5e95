#pragma once
// dispmap::vulkan::ComputePipeline: a compute shader with n storage buffers at bindings 0..n-1
// (set 0) and optional push constants and specialisation constants; run it with Context::dispatch.
#include <cstdint>
#include <span>

#include "dispmap/vulkan/context.h"

namespace dispmap::vulkan {

/// A 32-bit specialisation constant (int, uint or bool: 0 or 1) by constant_id.
struct SpecConstant {
    std::uint32_t id;
    std::uint32_t value;
};

/// Descriptor set layout, pipeline layout and compute pipeline (entry point "main"). Move-only;
/// must not outlive its Context.
class ComputePipeline {
  public:
    /// The most storage buffers one pipeline may bind.
    static constexpr std::uint32_t kMaxStorageBuffers = 16;

    /// spirv: a SPIR-V module (checked for its header; the validation layer checks the rest).
    /// ArgumentError for 0 or more than kMaxStorageBuffers buffers, or push constants that are not
    /// a multiple of 4 or exceed maxPushConstantsSize; VulkanError for a module that is not SPIR-V
    /// or a failed creation.
    ComputePipeline(Context& context, std::span<const std::uint32_t> spirv, std::uint32_t storageBuffers,
                    std::uint32_t pushConstantBytes = 0, std::span<const SpecConstant> specConstants = {});
    ~ComputePipeline();
    ComputePipeline(ComputePipeline&& other) noexcept;
    ComputePipeline& operator=(ComputePipeline&& other) noexcept;
    ComputePipeline(const ComputePipeline&) = delete;
    ComputePipeline& operator=(const ComputePipeline&) = delete;

    VkPipeline handle() const { return pipeline_; }
    VkPipelineLayout layout() const { return layout_; }
    VkDescriptorSetLayout setLayout() const { return setLayout_; }
    std::uint32_t storageBuffers() const { return storageBuffers_; }
    std::uint32_t pushConstantBytes() const { return pushConstantBytes_; }

  private:
    void release() noexcept;

    Context* context_ = nullptr;
    VkDescriptorSetLayout setLayout_ = VK_NULL_HANDLE;
    VkPipelineLayout layout_ = VK_NULL_HANDLE;
    VkPipeline pipeline_ = VK_NULL_HANDLE;
    std::uint32_t storageBuffers_ = 0;
    std::uint32_t pushConstantBytes_ = 0;
};

} // namespace dispmap::vulkan
