#pragma once
// The Vulkan objects both renderers (SurfaceRenderer, MesoRenderer) are built from: images,
// barriers, a descriptor set of storage buffers and sampled images with its pipeline layout,
// a graphics pipeline for dynamic rendering, offscreen targets with read-back, a timestamp
// pair. Internal to the backend (not installed). Image is move-only, the others neither copy
// nor move; each owns its Vulkan handles and must not outlive its Context; destroying one does
// not wait for the device.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "dispmap/vulkan/buffer.h"
#include "dispmap/vulkan/context.h"

namespace dispmap::vulkan::detail {

/// The median of v (NaN if empty).
double median(std::vector<double> v);

/// Whether format is a depth (or depth/stencil) format, and the aspect of its views.
bool isDepthFormat(VkFormat format);
VkImageAspectFlags aspectOf(VkFormat format);

/// VulkanError unless the device supports `feature` (optimal tiling) for `format`; `what` names its use.
void requireFormat(const Context& ctx, VkFormat format, VkFormatFeatureFlags feature, const char* what);

/// A 2D image (one mip, one layer, optimal tiling, device-local memory) with a view.
class Image {
  public:
    Image() = default;
    Image(Context& ctx, std::uint32_t width, std::uint32_t height, VkFormat format, VkImageUsageFlags usage);
    ~Image() { release(); }
    Image(Image&& o) noexcept { *this = std::move(o); }
    Image& operator=(Image&& o) noexcept;
    Image(const Image&) = delete;
    Image& operator=(const Image&) = delete;

    VkImage image() const { return image_; }
    VkImageView view() const { return view_; }
    VkFormat format() const { return format_; }
    VkImageAspectFlags aspect() const { return aspectOf(format_); }
    std::uint32_t width() const { return width_; }
    std::uint32_t height() const { return height_; }

  private:
    void release() noexcept;
    Context* ctx_ = nullptr;
    VkImage image_ = VK_NULL_HANDLE;
    VkDeviceMemory memory_ = VK_NULL_HANDLE;
    VkImageView view_ = VK_NULL_HANDLE;
    VkFormat format_ = VK_FORMAT_UNDEFINED;
    std::uint32_t width_ = 0, height_ = 0;
};

/// One image memory barrier (whole image, queue family ignored).
void imageBarrier(const Functions& fn, VkCommandBuffer cmd, VkImage image, VkImageAspectFlags aspect, VkImageLayout from,
                  VkImageLayout to, VkPipelineStageFlags srcStage, VkAccessFlags srcAccess, VkPipelineStageFlags dstStage,
                  VkAccessFlags dstAccess);
/// One global memory barrier.
void memoryBarrier(const Functions& fn, VkCommandBuffer cmd, VkPipelineStageFlags srcStage, VkAccessFlags srcAccess,
                   VkPipelineStageFlags dstStage, VkAccessFlags dstAccess);

/// Copies a whole image (in TRANSFER_SRC_OPTIMAL) to a buffer, tightly packed.
void copyImageToBuffer(const Functions& fn, VkCommandBuffer cmd, const Image& image, VkBuffer buffer);

/// Writes bytes to buffer at offset with vkCmdUpdateBuffer, in pieces of at most 64 KiB (the
/// call's limit); bytes and offset multiples of 4. Outside any render pass.
void updateBuffer(const Functions& fn, VkCommandBuffer cmd, VkBuffer buffer, const void* data, std::size_t bytes,
                  VkDeviceSize offset = 0);

/// A combined image sampler's contents (layout SHADER_READ_ONLY_OPTIMAL).
struct SampledImage {
    VkSampler sampler = VK_NULL_HANDLE;
    VkImageView view = VK_NULL_HANDLE;
};

/// Set 0 of a pipeline: storage buffers at bindings 0..n-1, then combined image samplers, all
/// visible to `stages`; its layout, pool, set (written once here) and the pipeline layout (no
/// push constants).
class DescriptorSet {
  public:
    DescriptorSet(Context& ctx, std::span<const VkBuffer> storage, std::span<const SampledImage> images,
                  VkShaderStageFlags stages);
    ~DescriptorSet();
    DescriptorSet(const DescriptorSet&) = delete;
    DescriptorSet& operator=(const DescriptorSet&) = delete;

    VkPipelineLayout pipelineLayout() const { return layout_; }
    /// Binds the set for graphics pipelines.
    void bind(VkCommandBuffer cmd) const;

  private:
    void release() noexcept;
    Context& ctx_;
    VkDescriptorSetLayout setLayout_ = VK_NULL_HANDLE;
    VkPipelineLayout layout_ = VK_NULL_HANDLE;
    VkDescriptorPool pool_ = VK_NULL_HANDLE;
    VkDescriptorSet set_ = VK_NULL_HANDLE;
};

/// One shader stage of a graphics pipeline: SPIR-V, and whether the pipeline's specialisation
/// constants apply to it.
struct ShaderStage {
    VkShaderStageFlagBits stage;
    std::span<const std::uint32_t> code;
    bool specialised = true;
};

/// What a graphics pipeline for dynamic rendering is made of. No vertex input (the shaders
/// pull their data), one viewport and scissor (dynamic state), one sample, no culling.
struct GraphicsPipelineDesc {
    std::vector<ShaderStage> stages;
    /// 32-bit specialisation constants: constant_id i = specConstants[i].
    std::vector<std::uint32_t> specConstants;
    VkPrimitiveTopology topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST;
    std::uint32_t patchControlPoints = 0; ///< > 0: tessellation (topology PATCH_LIST)
    VkPolygonMode polygonMode = VK_POLYGON_MODE_FILL;
    bool depthBias = false;
    float depthBiasConstant = 0.0f, depthBiasSlope = 0.0f;
    bool depthWrite = true;                   ///< depth test on whenever depthFormat is set
    VkCompareOp depthCompare = VK_COMPARE_OP_LESS;
    std::vector<VkFormat> colorFormats;       ///< VkPipelineRenderingCreateInfo, one per attachment
    std::vector<VkColorComponentFlags> colorWriteMasks; ///< per attachment (empty: all RGBA); no blending
    VkFormat depthFormat = VK_FORMAT_UNDEFINED; ///< UNDEFINED: no depth attachment
    VkPipelineLayout layout = VK_NULL_HANDLE;
};

class GraphicsPipeline {
  public:
    GraphicsPipeline(Context& ctx, const GraphicsPipelineDesc& desc);
    ~GraphicsPipeline();
    GraphicsPipeline(const GraphicsPipeline&) = delete;
    GraphicsPipeline& operator=(const GraphicsPipeline&) = delete;
    VkPipeline handle() const { return pipeline_; }

  private:
    Context& ctx_;
    VkPipeline pipeline_ = VK_NULL_HANDLE;
};

/// A GPU time span: two timestamps (none where the queue has no timestamps).
class Timestamps {
  public:
    explicit Timestamps(Context& ctx);
    ~Timestamps();
    Timestamps(const Timestamps&) = delete;
    Timestamps& operator=(const Timestamps&) = delete;
    /// Resets the pool and writes the first timestamp (top of pipe); outside any render pass.
    void begin(VkCommandBuffer cmd) const;
    /// Writes the second timestamp (bottom of pipe).
    void end(VkCommandBuffer cmd) const;
    /// Milliseconds between them, after the submission finished; NaN without timestamps.
    double milliseconds() const;

  private:
    Context& ctx_;
    VkQueryPool pool_ = VK_NULL_HANDLE;
};

/// Offscreen attachments of one size: colour images and an optional depth image, each with a
/// host-visible read-back buffer, recorded with dynamic rendering.
class OffscreenTargets {
  public:
    /// depthFormat UNDEFINED: no depth attachment.
    OffscreenTargets(Context& ctx, int width, int height, std::span<const VkFormat> colorFormats, VkFormat depthFormat);
    int width() const { return width_; }
    int height() const { return height_; }
    /// Moves every attachment from any layout to its attachment layout (contents discarded)
    /// and begins rendering over the whole image with clears (one per colour attachment; depth
    /// cleared to depthClear), stored at the end.
    void beginRendering(VkCommandBuffer cmd, std::span<const VkClearColorValue> colorClears, float depthClear = 1.0f) const;
    void endRendering(VkCommandBuffer cmd) const;
    /// After endRendering: copies every attachment to its read-back buffer (colours, then
    /// depth). The caller adds the barrier to the host (TRANSFER_WRITE -> HOST_READ).
    void copyToReadBack(VkCommandBuffer cmd) const;
    /// The read-back of attachment i: colour i, or the depth after the colours.
    const Buffer& readBack(std::size_t i) const { return readBack_[i]; }

  private:
    Context& ctx_;
    int width_, height_;
    std::vector<Image> colors_;
    Image depth_;
    std::vector<Buffer> readBack_;
};

} // namespace dispmap::vulkan::detail
