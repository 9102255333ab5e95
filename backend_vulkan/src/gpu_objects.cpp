// The shared Vulkan objects of the renderers (gpu_objects.h).
#include "gpu_objects.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

namespace dispmap::vulkan::detail {

double median(std::vector<double> v) {
    if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
    std::sort(v.begin(), v.end());
    const std::size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

bool isDepthFormat(VkFormat format) {
    switch (format) {
    case VK_FORMAT_D16_UNORM:
    case VK_FORMAT_X8_D24_UNORM_PACK32:
    case VK_FORMAT_D32_SFLOAT:
    case VK_FORMAT_D16_UNORM_S8_UINT:
    case VK_FORMAT_D24_UNORM_S8_UINT:
    case VK_FORMAT_D32_SFLOAT_S8_UINT:
        return true;
    default:
        return false;
    }
}

VkImageAspectFlags aspectOf(VkFormat format) {
    return isDepthFormat(format) ? VK_IMAGE_ASPECT_DEPTH_BIT : VK_IMAGE_ASPECT_COLOR_BIT;
}

namespace {

/// Bytes per texel of the formats the offscreen targets read back.
std::size_t texelBytes(VkFormat format) {
    switch (format) {
    case VK_FORMAT_R8G8B8A8_UNORM:
    case VK_FORMAT_B8G8R8A8_UNORM:
    case VK_FORMAT_R32_SFLOAT:
    case VK_FORMAT_D32_SFLOAT:
        return 4;
    case VK_FORMAT_R32G32B32A32_SFLOAT:
    case VK_FORMAT_R32G32B32A32_UINT:
        return 16;
    default:
        throw VulkanError("offscreen target: no read-back for VkFormat " + std::to_string(static_cast<int>(format)));
    }
}

constexpr VkColorComponentFlags kRgba =
    VK_COLOR_COMPONENT_R_BIT | VK_COLOR_COMPONENT_G_BIT | VK_COLOR_COMPONENT_B_BIT | VK_COLOR_COMPONENT_A_BIT;

} // namespace

void requireFormat(const Context& ctx, VkFormat format, VkFormatFeatureFlags feature, const char* what) {
    VkFormatProperties props{};
    ctx.fn().vkGetPhysicalDeviceFormatProperties(ctx.physicalDevice(), format, &props);
    if ((props.optimalTilingFeatures & feature) != feature)
        throw VulkanError("Vulkan device '" + ctx.deviceName() + "' does not support VkFormat " +
                          std::to_string(static_cast<int>(format)) + " as " + what);
}

// --- Image

Image::Image(Context& ctx, std::uint32_t width, std::uint32_t height, VkFormat format, VkImageUsageFlags usage)
    : ctx_(&ctx), format_(format), width_(width), height_(height) {
    const Functions& fn = ctx.fn();
    try {
        VkImageCreateInfo info{};
        info.sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO;
        info.imageType = VK_IMAGE_TYPE_2D;
        info.format = format;
        info.extent = {width, height, 1};
        info.mipLevels = 1;
        info.arrayLayers = 1;
        info.samples = VK_SAMPLE_COUNT_1_BIT;
        info.tiling = VK_IMAGE_TILING_OPTIMAL;
        info.usage = usage;
        info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
        info.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
        DISPMAP_VK_CHECK(fn, vkCreateImage, ctx.device(), &info, nullptr, &image_);
        VkMemoryRequirements needs{};
        fn.vkGetImageMemoryRequirements(ctx.device(), image_, &needs);
        VkMemoryAllocateInfo alloc{};
        alloc.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
        alloc.allocationSize = needs.size;
        alloc.memoryTypeIndex = ctx.findMemoryType(needs.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
        DISPMAP_VK_CHECK(fn, vkAllocateMemory, ctx.device(), &alloc, nullptr, &memory_);
        DISPMAP_VK_CHECK(fn, vkBindImageMemory, ctx.device(), image_, memory_, 0);
        VkImageViewCreateInfo view{};
        view.sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO;
        view.image = image_;
        view.viewType = VK_IMAGE_VIEW_TYPE_2D;
        view.format = format;
        view.subresourceRange = {aspectOf(format), 0, 1, 0, 1};
        DISPMAP_VK_CHECK(fn, vkCreateImageView, ctx.device(), &view, nullptr, &view_);
    } catch (...) {
        release();
        throw;
    }
}

Image& Image::operator=(Image&& o) noexcept {
    if (this != &o) {
        release();
        ctx_ = std::exchange(o.ctx_, nullptr);
        image_ = std::exchange(o.image_, VK_NULL_HANDLE);
        memory_ = std::exchange(o.memory_, VK_NULL_HANDLE);
        view_ = std::exchange(o.view_, VK_NULL_HANDLE);
        format_ = std::exchange(o.format_, VK_FORMAT_UNDEFINED);
        width_ = std::exchange(o.width_, 0u);
        height_ = std::exchange(o.height_, 0u);
    }
    return *this;
}

void Image::release() noexcept {
    if (!ctx_) return;
    const Functions& fn = ctx_->fn();
    if (view_) fn.vkDestroyImageView(ctx_->device(), view_, nullptr);
    if (image_) fn.vkDestroyImage(ctx_->device(), image_, nullptr);
    if (memory_) fn.vkFreeMemory(ctx_->device(), memory_, nullptr);
    view_ = VK_NULL_HANDLE;
    image_ = VK_NULL_HANDLE;
    memory_ = VK_NULL_HANDLE;
    ctx_ = nullptr;
}

// --- Barriers and copies

void imageBarrier(const Functions& fn, VkCommandBuffer cmd, VkImage image, VkImageAspectFlags aspect, VkImageLayout from,
                  VkImageLayout to, VkPipelineStageFlags srcStage, VkAccessFlags srcAccess, VkPipelineStageFlags dstStage,
                  VkAccessFlags dstAccess) {
    VkImageMemoryBarrier b{};
    b.sType = VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER;
    b.srcAccessMask = srcAccess;
    b.dstAccessMask = dstAccess;
    b.oldLayout = from;
    b.newLayout = to;
    b.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    b.image = image;
    b.subresourceRange = {aspect, 0, 1, 0, 1};
    fn.vkCmdPipelineBarrier(cmd, srcStage, dstStage, 0, 0, nullptr, 0, nullptr, 1, &b);
}

void memoryBarrier(const Functions& fn, VkCommandBuffer cmd, VkPipelineStageFlags srcStage, VkAccessFlags srcAccess,
                   VkPipelineStageFlags dstStage, VkAccessFlags dstAccess) {
    VkMemoryBarrier b{};
    b.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
    b.srcAccessMask = srcAccess;
    b.dstAccessMask = dstAccess;
    fn.vkCmdPipelineBarrier(cmd, srcStage, dstStage, 0, 1, &b, 0, nullptr, 0, nullptr);
}

void copyImageToBuffer(const Functions& fn, VkCommandBuffer cmd, const Image& image, VkBuffer buffer) {
    VkBufferImageCopy region{};
    region.imageExtent = {image.width(), image.height(), 1};
    region.imageSubresource = {image.aspect(), 0, 0, 1};
    fn.vkCmdCopyImageToBuffer(cmd, image.image(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, buffer, 1, &region);
}

void updateBuffer(const Functions& fn, VkCommandBuffer cmd, VkBuffer buffer, const void* data, std::size_t bytes,
                  VkDeviceSize offset) {
    constexpr std::size_t kPiece = 65536;
    const auto* p = static_cast<const std::uint8_t*>(data);
    for (std::size_t done = 0; done < bytes; done += kPiece) {
        const std::size_t n = std::min(kPiece, bytes - done);
        fn.vkCmdUpdateBuffer(cmd, buffer, offset + done, n, p + done);
    }
}

// --- DescriptorSet

DescriptorSet::DescriptorSet(Context& ctx, std::span<const VkBuffer> storage, std::span<const SampledImage> images,
                             VkShaderStageFlags stages)
    : ctx_(ctx) {
    const Functions& fn = ctx.fn();
    const auto nb = static_cast<std::uint32_t>(storage.size()), ni = static_cast<std::uint32_t>(images.size());
    const std::uint32_t n = nb + ni;
    try {
        std::vector<VkDescriptorSetLayoutBinding> b(n);
        for (std::uint32_t i = 0; i < n; ++i)
            b[i] = {i, i < nb ? VK_DESCRIPTOR_TYPE_STORAGE_BUFFER : VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, stages, nullptr};
        VkDescriptorSetLayoutCreateInfo li{};
        li.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO;
        li.bindingCount = n;
        li.pBindings = b.data();
        DISPMAP_VK_CHECK(fn, vkCreateDescriptorSetLayout, ctx.device(), &li, nullptr, &setLayout_);
        VkPipelineLayoutCreateInfo pl{};
        pl.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO;
        pl.setLayoutCount = 1;
        pl.pSetLayouts = &setLayout_;
        DISPMAP_VK_CHECK(fn, vkCreatePipelineLayout, ctx.device(), &pl, nullptr, &layout_);
        std::vector<VkDescriptorPoolSize> sizes;
        if (nb) sizes.push_back({VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, nb});
        if (ni) sizes.push_back({VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, ni});
        VkDescriptorPoolCreateInfo pi{};
        pi.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO;
        pi.maxSets = 1;
        pi.poolSizeCount = static_cast<std::uint32_t>(sizes.size());
        pi.pPoolSizes = sizes.data();
        DISPMAP_VK_CHECK(fn, vkCreateDescriptorPool, ctx.device(), &pi, nullptr, &pool_);
        VkDescriptorSetAllocateInfo ai{};
        ai.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO;
        ai.descriptorPool = pool_;
        ai.descriptorSetCount = 1;
        ai.pSetLayouts = &setLayout_;
        DISPMAP_VK_CHECK(fn, vkAllocateDescriptorSets, ctx.device(), &ai, &set_);
        std::vector<VkDescriptorBufferInfo> bufferInfos(nb);
        std::vector<VkDescriptorImageInfo> imageInfos(ni);
        std::vector<VkWriteDescriptorSet> writes(n);
        for (std::uint32_t i = 0; i < n; ++i) {
            writes[i].sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
            writes[i].dstSet = set_;
            writes[i].dstBinding = i;
            writes[i].descriptorCount = 1;
            if (i < nb) {
                bufferInfos[i] = {storage[i], 0, VK_WHOLE_SIZE};
                writes[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
                writes[i].pBufferInfo = &bufferInfos[i];
            } else {
                imageInfos[i - nb] = {images[i - nb].sampler, images[i - nb].view, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
                writes[i].descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER;
                writes[i].pImageInfo = &imageInfos[i - nb];
            }
        }
        fn.vkUpdateDescriptorSets(ctx.device(), n, writes.data(), 0, nullptr);
    } catch (...) {
        release();
        throw;
    }
}

DescriptorSet::~DescriptorSet() { release(); }

void DescriptorSet::release() noexcept {
    const Functions& fn = ctx_.fn();
    if (pool_) fn.vkDestroyDescriptorPool(ctx_.device(), pool_, nullptr);
    if (layout_) fn.vkDestroyPipelineLayout(ctx_.device(), layout_, nullptr);
    if (setLayout_) fn.vkDestroyDescriptorSetLayout(ctx_.device(), setLayout_, nullptr);
    pool_ = VK_NULL_HANDLE;
    layout_ = VK_NULL_HANDLE;
    setLayout_ = VK_NULL_HANDLE;
}

void DescriptorSet::bind(VkCommandBuffer cmd) const {
    ctx_.fn().vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, layout_, 0, 1, &set_, 0, nullptr);
}

// --- GraphicsPipeline

GraphicsPipeline::GraphicsPipeline(Context& ctx, const GraphicsPipelineDesc& d) : ctx_(ctx) {
    const Functions& fn = ctx.fn();
    const auto nSpec = static_cast<std::uint32_t>(d.specConstants.size());
    std::vector<VkSpecializationMapEntry> entries(nSpec);
    for (std::uint32_t i = 0; i < nSpec; ++i) entries[i] = {i, i * 4, 4};
    const VkSpecializationInfo si{nSpec, entries.data(), nSpec * sizeof(std::uint32_t), d.specConstants.data()};
    std::vector<VkShaderModule> modules(d.stages.size(), VK_NULL_HANDLE);
    std::vector<VkPipelineShaderStageCreateInfo> infos(d.stages.size());
    try {
        for (std::size_t i = 0; i < d.stages.size(); ++i) {
            VkShaderModuleCreateInfo mi{};
            mi.sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO;
            mi.codeSize = d.stages[i].code.size_bytes();
            mi.pCode = d.stages[i].code.data();
            DISPMAP_VK_CHECK(fn, vkCreateShaderModule, ctx.device(), &mi, nullptr, &modules[i]);
            infos[i].sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
            infos[i].stage = d.stages[i].stage;
            infos[i].module = modules[i];
            infos[i].pName = "main";
            infos[i].pSpecializationInfo = d.stages[i].specialised && nSpec ? &si : nullptr;
        }
        const bool tessellation = d.patchControlPoints > 0;
        VkPipelineVertexInputStateCreateInfo vi{};
        vi.sType = VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO;
        VkPipelineInputAssemblyStateCreateInfo ia{};
        ia.sType = VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO;
        ia.topology = tessellation ? VK_PRIMITIVE_TOPOLOGY_PATCH_LIST : d.topology;
        VkPipelineTessellationStateCreateInfo ts{};
        ts.sType = VK_STRUCTURE_TYPE_PIPELINE_TESSELLATION_STATE_CREATE_INFO;
        ts.patchControlPoints = d.patchControlPoints;
        VkPipelineViewportStateCreateInfo vp{};
        vp.sType = VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO;
        vp.viewportCount = 1;
        vp.scissorCount = 1;
        VkPipelineRasterizationStateCreateInfo rs{};
        rs.sType = VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO;
        rs.polygonMode = d.polygonMode;
        rs.cullMode = VK_CULL_MODE_NONE; // open meshes and holes show their inside
        rs.frontFace = VK_FRONT_FACE_COUNTER_CLOCKWISE;
        rs.lineWidth = 1.0f;
        rs.depthBiasEnable = d.depthBias ? VK_TRUE : VK_FALSE;
        rs.depthBiasConstantFactor = d.depthBiasConstant;
        rs.depthBiasSlopeFactor = d.depthBiasSlope;
        VkPipelineMultisampleStateCreateInfo ms{};
        ms.sType = VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO;
        ms.rasterizationSamples = VK_SAMPLE_COUNT_1_BIT;
        VkPipelineDepthStencilStateCreateInfo ds{};
        ds.sType = VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO;
        ds.depthTestEnable = VK_TRUE;
        ds.depthWriteEnable = d.depthWrite ? VK_TRUE : VK_FALSE;
        ds.depthCompareOp = d.depthCompare;
        std::vector<VkPipelineColorBlendAttachmentState> blend(d.colorFormats.size());
        for (std::size_t i = 0; i < blend.size(); ++i) blend[i].colorWriteMask = i < d.colorWriteMasks.size() ? d.colorWriteMasks[i] : kRgba;
        VkPipelineColorBlendStateCreateInfo cb{};
        cb.sType = VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO;
        cb.attachmentCount = static_cast<std::uint32_t>(blend.size());
        cb.pAttachments = blend.data();
        const VkDynamicState dyn[2] = {VK_DYNAMIC_STATE_VIEWPORT, VK_DYNAMIC_STATE_SCISSOR};
        VkPipelineDynamicStateCreateInfo dy{};
        dy.sType = VK_STRUCTURE_TYPE_PIPELINE_DYNAMIC_STATE_CREATE_INFO;
        dy.dynamicStateCount = 2;
        dy.pDynamicStates = dyn;
        VkPipelineRenderingCreateInfo rendering{};
        rendering.sType = VK_STRUCTURE_TYPE_PIPELINE_RENDERING_CREATE_INFO;
        rendering.colorAttachmentCount = static_cast<std::uint32_t>(d.colorFormats.size());
        rendering.pColorAttachmentFormats = d.colorFormats.data();
        rendering.depthAttachmentFormat = d.depthFormat;
        VkGraphicsPipelineCreateInfo gi{};
        gi.sType = VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO;
        gi.pNext = &rendering;
        gi.stageCount = static_cast<std::uint32_t>(infos.size());
        gi.pStages = infos.data();
        gi.pVertexInputState = &vi;
        gi.pInputAssemblyState = &ia;
        gi.pTessellationState = tessellation ? &ts : nullptr;
        gi.pViewportState = &vp;
        gi.pRasterizationState = &rs;
        gi.pMultisampleState = &ms;
        gi.pDepthStencilState = d.depthFormat != VK_FORMAT_UNDEFINED ? &ds : nullptr;
        gi.pColorBlendState = &cb;
        gi.pDynamicState = &dy;
        gi.layout = d.layout;
        DISPMAP_VK_CHECK(fn, vkCreateGraphicsPipelines, ctx.device(), VK_NULL_HANDLE, 1, &gi, nullptr, &pipeline_);
    } catch (...) {
        for (VkShaderModule m : modules)
            if (m) fn.vkDestroyShaderModule(ctx.device(), m, nullptr);
        throw;
    }
    for (VkShaderModule m : modules) fn.vkDestroyShaderModule(ctx.device(), m, nullptr);
}

GraphicsPipeline::~GraphicsPipeline() {
    if (pipeline_) ctx_.fn().vkDestroyPipeline(ctx_.device(), pipeline_, nullptr);
}

// --- Timestamps

Timestamps::Timestamps(Context& ctx) : ctx_(ctx) {
    if (!ctx.timestampsSupported()) return;
    VkQueryPoolCreateInfo qi{};
    qi.sType = VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO;
    qi.queryType = VK_QUERY_TYPE_TIMESTAMP;
    qi.queryCount = 2;
    DISPMAP_VK_CHECK(ctx.fn(), vkCreateQueryPool, ctx.device(), &qi, nullptr, &pool_);
}

Timestamps::~Timestamps() {
    if (pool_) ctx_.fn().vkDestroyQueryPool(ctx_.device(), pool_, nullptr);
}

void Timestamps::begin(VkCommandBuffer cmd) const {
    if (!pool_) return;
    ctx_.fn().vkCmdResetQueryPool(cmd, pool_, 0, 2);
    ctx_.fn().vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, pool_, 0);
}

void Timestamps::end(VkCommandBuffer cmd) const {
    if (pool_) ctx_.fn().vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, pool_, 1);
}

double Timestamps::milliseconds() const {
    if (!pool_) return std::numeric_limits<double>::quiet_NaN();
    std::uint64_t t[2] = {0, 0};
    DISPMAP_VK_CHECK(ctx_.fn(), vkGetQueryPoolResults, ctx_.device(), pool_, 0, 2, sizeof t, t, sizeof(std::uint64_t),
                     VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT);
    return double(t[1] - t[0]) * ctx_.timestampPeriodNs() * 1e-6;
}

// --- OffscreenTargets

OffscreenTargets::OffscreenTargets(Context& ctx, int width, int height, std::span<const VkFormat> colorFormats,
                                   VkFormat depthFormat)
    : ctx_(ctx), width_(width), height_(height) {
    const auto w = static_cast<std::uint32_t>(width), h = static_cast<std::uint32_t>(height);
    const std::size_t pixels = std::size_t(w) * std::size_t(h);
    for (const VkFormat f : colorFormats) {
        colors_.emplace_back(ctx, w, h, f, VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT);
        readBack_.emplace_back(ctx, pixels * texelBytes(f));
    }
    if (depthFormat != VK_FORMAT_UNDEFINED) {
        depth_ = Image(ctx, w, h, depthFormat, VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT);
        readBack_.emplace_back(ctx, pixels * texelBytes(depthFormat));
    }
}

void OffscreenTargets::beginRendering(VkCommandBuffer cmd, std::span<const VkClearColorValue> colorClears, float depthClear) const {
    const Functions& fn = ctx_.fn();
    // The previous frame's copies read these images: wait for them, then discard the contents.
    for (const Image& c : colors_)
        imageBarrier(fn, cmd, c.image(), c.aspect(), VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
                     VK_PIPELINE_STAGE_TRANSFER_BIT | VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT, 0,
                     VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT,
                     VK_ACCESS_COLOR_ATTACHMENT_READ_BIT | VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT);
    if (depth_.image())
        imageBarrier(fn, cmd, depth_.image(), depth_.aspect(), VK_IMAGE_LAYOUT_UNDEFINED,
                     VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL,
                     VK_PIPELINE_STAGE_TRANSFER_BIT | VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT, 0,
                     VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT,
                     VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_READ_BIT | VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT);
    std::vector<VkRenderingAttachmentInfo> colors(colors_.size());
    for (std::size_t i = 0; i < colors.size(); ++i) {
        colors[i].sType = VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO;
        colors[i].imageView = colors_[i].view();
        colors[i].imageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
        colors[i].loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
        colors[i].storeOp = VK_ATTACHMENT_STORE_OP_STORE;
        colors[i].clearValue.color = i < colorClears.size() ? colorClears[i] : VkClearColorValue{};
    }
    VkRenderingAttachmentInfo depth{};
    depth.sType = VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO;
    depth.imageView = depth_.view();
    depth.imageLayout = VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL;
    depth.loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
    depth.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    depth.clearValue.depthStencil = {depthClear, 0};
    VkRenderingInfo info{};
    info.sType = VK_STRUCTURE_TYPE_RENDERING_INFO;
    info.renderArea = {{0, 0}, {static_cast<std::uint32_t>(width_), static_cast<std::uint32_t>(height_)}};
    info.layerCount = 1;
    info.colorAttachmentCount = static_cast<std::uint32_t>(colors.size());
    info.pColorAttachments = colors.data();
    info.pDepthAttachment = depth_.image() ? &depth : nullptr;
    fn.vkCmdBeginRendering(cmd, &info);
}

void OffscreenTargets::endRendering(VkCommandBuffer cmd) const { ctx_.fn().vkCmdEndRendering(cmd); }

void OffscreenTargets::copyToReadBack(VkCommandBuffer cmd) const {
    const Functions& fn = ctx_.fn();
    for (std::size_t i = 0; i < colors_.size(); ++i) {
        imageBarrier(fn, cmd, colors_[i].image(), colors_[i].aspect(), VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
                     VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT,
                     VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT);
        copyImageToBuffer(fn, cmd, colors_[i], readBack_[i].handle());
    }
    if (depth_.image()) {
        imageBarrier(fn, cmd, depth_.image(), depth_.aspect(), VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL,
                     VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                     VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT,
                     VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT);
        copyImageToBuffer(fn, cmd, depth_, readBack_.back().handle());
    }
}

} // namespace dispmap::vulkan::detail
