// Compute pipelines (storage buffers, push constants, specialisation constants) and
// Context::dispatch: descriptor set, timestamps around the dispatch, barrier to the host, wait.
#include "dispmap/vulkan/compute.h"

#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "dispmap/vulkan/buffer.h"

namespace dispmap::vulkan {

namespace {

constexpr std::uint32_t kSpirvMagic = 0x07230203u;

/// Throws VulkanError unless spirv has a SPIR-V header this API version accepts (1.0 to 1.5). A
/// malformed module body is caught by the validation layer, not here.
void checkSpirvHeader(std::span<const std::uint32_t> spirv) {
    if (spirv.size() < 5 || spirv[0] != kSpirvMagic)
        throw VulkanError("compute shader is not a SPIR-V module (" + std::to_string(spirv.size()) +
                          " words, " + (spirv.empty() ? "no magic number" : "wrong magic number") + ")");
    const std::uint32_t major = (spirv[1] >> 16) & 0xffu, minor = (spirv[1] >> 8) & 0xffu;
    if (major != 1 || minor > 5)
        throw VulkanError("compute shader is SPIR-V " + std::to_string(major) + "." + std::to_string(minor) +
                          "; Vulkan 1.2 accepts 1.0 to 1.5 (compile with --target-env vulkan1.2)");
}

} // namespace

ComputePipeline::ComputePipeline(Context& context, std::span<const std::uint32_t> spirv,
                                 std::uint32_t storageBuffers, std::uint32_t pushConstantBytes,
                                 std::span<const SpecConstant> specConstants)
    : context_(&context), storageBuffers_(storageBuffers), pushConstantBytes_(pushConstantBytes) {
    if (storageBuffers == 0 || storageBuffers > kMaxStorageBuffers)
        throw ArgumentError("compute pipeline with " + std::to_string(storageBuffers) +
                            " storage buffers; 1 to " + std::to_string(kMaxStorageBuffers) +
                            " are supported");
    const std::uint32_t maxPush = context.properties().limits.maxPushConstantsSize;
    if (pushConstantBytes % 4 != 0 || pushConstantBytes > maxPush)
        throw ArgumentError(
            "compute pipeline push constants of " + std::to_string(pushConstantBytes) +
            " bytes; must be a multiple of 4 and at most maxPushConstantsSize = " + std::to_string(maxPush));
    checkSpirvHeader(spirv);

    const Functions& fn = context.fn();
    const VkDevice device = context.device();
    VkShaderModule module = VK_NULL_HANDLE;
    try {
        std::vector<VkDescriptorSetLayoutBinding> bindings(storageBuffers);
        for (std::uint32_t i = 0; i < storageBuffers; ++i)
            bindings[i] = {i, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr};
        VkDescriptorSetLayoutCreateInfo setInfo{};
        setInfo.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO;
        setInfo.bindingCount = storageBuffers;
        setInfo.pBindings = bindings.data();
        DISPMAP_VK_CHECK(fn, vkCreateDescriptorSetLayout, device, &setInfo, nullptr, &setLayout_);

        const VkPushConstantRange pushRange{VK_SHADER_STAGE_COMPUTE_BIT, 0, pushConstantBytes};
        VkPipelineLayoutCreateInfo layoutInfo{};
        layoutInfo.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO;
        layoutInfo.setLayoutCount = 1;
        layoutInfo.pSetLayouts = &setLayout_;
        layoutInfo.pushConstantRangeCount = pushConstantBytes > 0 ? 1 : 0;
        layoutInfo.pPushConstantRanges = &pushRange;
        DISPMAP_VK_CHECK(fn, vkCreatePipelineLayout, device, &layoutInfo, nullptr, &layout_);

        VkShaderModuleCreateInfo moduleInfo{};

        moduleInfo.sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO;
        moduleInfo.codeSize = spirv.size_bytes();
        moduleInfo.pCode = spirv.data();
        DISPMAP_VK_CHECK(fn, vkCreateShaderModule, device, &moduleInfo, nullptr, &module);

        std::vector<VkSpecializationMapEntry> entries;
        std::vector<std::uint32_t> values;
        for (const SpecConstant& c : specConstants) {
            entries.push_back({c.id, static_cast<std::uint32_t>(values.size() * 4), 4});
            values.push_back(c.value);
        }
        VkSpecializationInfo specInfo{static_cast<std::uint32_t>(entries.size()), entries.data(),
                                      values.size() * 4, values.data()};
        VkComputePipelineCreateInfo info{};
        info.sType = VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO;
        info.stage = {};
        info.stage.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
        info.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
        info.stage.module = module;
        info.stage.pName = "main";
        info.stage.pSpecializationInfo = entries.empty() ? nullptr : &specInfo;
        info.layout = layout_;
        DISPMAP_VK_CHECK(fn, vkCreateComputePipelines, device, VK_NULL_HANDLE, 1, &info, nullptr, &pipeline_);
        fn.vkDestroyShaderModule(device, module, nullptr);
    } catch (...) {
        if (module) fn.vkDestroyShaderModule(device, module, nullptr);
        release();
        throw;
    }
}

ComputePipeline::~ComputePipeline() {
    release();
}

ComputePipeline::ComputePipeline(ComputePipeline&& other) noexcept
    : context_(std::exchange(other.context_, nullptr)),
      setLayout_(std::exchange(other.setLayout_, VK_NULL_HANDLE)),
      layout_(std::exchange(other.layout_, VK_NULL_HANDLE)),
      pipeline_(std::exchange(other.pipeline_, VK_NULL_HANDLE)),
      storageBuffers_(std::exchange(other.storageBuffers_, 0)),
      pushConstantBytes_(std::exchange(other.pushConstantBytes_, 0)) {}

ComputePipeline& ComputePipeline::operator=(ComputePipeline&& other) noexcept {
    if (this != &other) {
        release();
        context_ = std::exchange(other.context_, nullptr);
        setLayout_ = std::exchange(other.setLayout_, VK_NULL_HANDLE);
        layout_ = std::exchange(other.layout_, VK_NULL_HANDLE);
        pipeline_ = std::exchange(other.pipeline_, VK_NULL_HANDLE);
        storageBuffers_ = std::exchange(other.storageBuffers_, 0);
        pushConstantBytes_ = std::exchange(other.pushConstantBytes_, 0);
    }
    return *this;
}

void ComputePipeline::release() noexcept {
    if (!context_) return;
    const Functions& fn = context_->fn();
    const VkDevice device = context_->device();
    if (pipeline_) fn.vkDestroyPipeline(device, pipeline_, nullptr);
    if (layout_) fn.vkDestroyPipelineLayout(device, layout_, nullptr);
    if (setLayout_) fn.vkDestroyDescriptorSetLayout(device, setLayout_, nullptr);
    pipeline_ = VK_NULL_HANDLE;
    layout_ = VK_NULL_HANDLE;
    setLayout_ = VK_NULL_HANDLE;
    context_ = nullptr;
}

double Context::dispatch(const ComputePipeline& pipeline, std::span<const Buffer* const> buffers,
                         glm::uvec3 groups, const void* push, std::size_t pushBytes) {
    if (!pipeline.handle()) throw ArgumentError("dispatch of an empty (moved-from) compute pipeline");
    if (buffers.size() != pipeline.storageBuffers())
        throw ArgumentError("dispatch with " + std::to_string(buffers.size()) +
                            " buffers; the pipeline has " + std::to_string(pipeline.storageBuffers()) +
                            " storage buffer bindings");
    for (std::size_t i = 0; i < buffers.size(); ++i) {
        if (!buffers[i] || !buffers[i]->handle())
            throw ArgumentError("dispatch: buffer " + std::to_string(i) + " is null or empty");
        if (buffers[i]->size() > properties_.limits.maxStorageBufferRange)
            throw ArgumentError("dispatch: buffer " + std::to_string(i) + " of " +
                                std::to_string(buffers[i]->size()) +
                                " bytes exceeds maxStorageBufferRange = " +
                                std::to_string(properties_.limits.maxStorageBufferRange));
    }
    if (pushBytes != pipeline.pushConstantBytes() || (pushBytes > 0 && !push))
        throw ArgumentError("dispatch with " + std::to_string(pushBytes) + " bytes of push constants" +
                            (pushBytes > 0 && !push ? " from a null pointer" : "") + "; the pipeline has " +
                            std::to_string(pipeline.pushConstantBytes()));
    for (int i = 0; i < 3; ++i) {
        const std::uint32_t limit = properties_.limits.maxComputeWorkGroupCount[i];
        if (groups[i] > limit)
            throw ArgumentError("dispatch of " + std::to_string(groups[i]) + " work groups in " + "xyz"[i] +
                                " exceeds maxComputeWorkGroupCount[" + std::to_string(i) +
                                "] = " + std::to_string(limit));
    }

    DISPMAP_VK_CHECK(fn_, vkResetDescriptorPool, device_, descriptorPool_, 0);
    VkDescriptorSet set = VK_NULL_HANDLE;
    const VkDescriptorSetLayout setLayout = pipeline.setLayout();
    VkDescriptorSetAllocateInfo allocation{};
    allocation.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO;
    allocation.descriptorPool = descriptorPool_;
    allocation.descriptorSetCount = 1;
    allocation.pSetLayouts = &setLayout;
    DISPMAP_VK_CHECK(fn_, vkAllocateDescriptorSets, device_, &allocation, &set);
    std::array<VkDescriptorBufferInfo, ComputePipeline::kMaxStorageBuffers> infos{};
    std::array<VkWriteDescriptorSet, ComputePipeline::kMaxStorageBuffers> writes{};
    for (std::uint32_t i = 0; i < buffers.size(); ++i) {
        infos[i] = {buffers[i]->handle(), 0, VK_WHOLE_SIZE};
        writes[i] = {};
        writes[i].sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
        writes[i].dstSet = set;
        writes[i].dstBinding = i;
        writes[i].descriptorCount = 1;
        writes[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
        writes[i].pBufferInfo = &infos[i];
    }
    fn_.vkUpdateDescriptorSets(device_, pipeline.storageBuffers(), writes.data(), 0, nullptr);

    submitAndWait([&](VkCommandBuffer cmd) {
        if (queryPool_) fn_.vkCmdResetQueryPool(cmd, queryPool_, 0, 2);
        fn_.vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline.handle());
        fn_.vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline.layout(), 0, 1, &set, 0,
                                    nullptr);
        if (pushBytes > 0)
            fn_.vkCmdPushConstants(cmd, pipeline.layout(), VK_SHADER_STAGE_COMPUTE_BIT, 0,
                                   static_cast<std::uint32_t>(pushBytes), push);
        if (queryPool_) fn_.vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, queryPool_, 0);
        fn_.vkCmdDispatch(cmd, groups.x, groups.y, groups.z);
        if (queryPool_) fn_.vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, queryPool_, 1);
        VkMemoryBarrier barrier{};
        barrier.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
        barrier.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
        barrier.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
        fn_.vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1,
                                 &barrier, 0, nullptr, 0, nullptr);
    });

    if (!queryPool_) return std::numeric_limits<double>::quiet_NaN();
    std::array<std::uint64_t, 2> ticks{};
    DISPMAP_VK_CHECK(fn_, vkGetQueryPoolResults, device_, queryPool_, 0, 2, sizeof ticks, ticks.data(),
                     sizeof(std::uint64_t), VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT);
    const std::uint64_t mask = timestampBits_ >= 64 ? ~0ull : (1ull << timestampBits_) - 1;
    const std::uint64_t elapsed = (ticks[1] - ticks[0]) & mask;
    return static_cast<double>(elapsed) * timestampPeriodNs() * 1e-9;
}

} // namespace dispmap::vulkan
