// Draw a displaced surface into your own Vulkan images, as an engine does: the renderer records
// into your command buffer, inside your vkCmdBeginRendering, with your attachment formats.
//
//   draw_surface [OUT.png]
//
// Layers used: surface/ (a built-in cage and its tiles), io/ (the PNG) and the Vulkan backend:
// Context (instance and device; an engine wraps its own in Context(ExternalDevice{...})), Buffer
// for the read-back, SurfaceRenderer. The command buffer, images and rendering are this file's.
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "dispmap/io/png.h"
#include "dispmap/surface/builtin.h"
#include "dispmap/surface/tile_builder.h"
#include "dispmap/vulkan/buffer.h"
#include "dispmap/vulkan/renderer.h"

int main(int argc, char** argv) {
    namespace dv = dispmap::vulkan;
    const std::string out = argc > 1 ? argv[1] : "draw_surface.png";
    try {
        const dispmap::ControlMesh mesh = dispmap::builtin::defaultMesh();
        const dispmap::TileSet tiles = dispmap::buildTiles(mesh, dispmap::uniformTileSizes(mesh, 5),
                                                           dispmap::FunctionSource(dispmap::builtin::defaultDisplacement));
        const dispmap::BaseSurface base(mesh);
        const dispmap::DisplacedSurface surface(base, tiles);
        dispmap::SurfaceDraw draw; // 320 x 240, one light; the effects are specialisation constants
        draw.camera.eye = {2.6, 2.0, 3.4};
        draw.effects.tessValue = 16;

        dv::Context ctx; // lavapipe unless DISPMAP_VK_DEVICE names another device
        const dv::Functions& fn = ctx.fn();
        const VkDevice device = ctx.device();
        dv::RendererOptions options; // draw into a BGRA colour + D32 depth target of ours
        options.target = dv::TargetFormats{VK_FORMAT_B8G8R8A8_UNORM, VK_FORMAT_UNDEFINED, VK_FORMAT_D32_SFLOAT};
        dv::SurfaceRenderer renderer(ctx, draw, surface, nullptr, options);

        // Our images, command buffer and fence.
        const VkExtent2D size{static_cast<std::uint32_t>(draw.width), static_cast<std::uint32_t>(draw.height)};
        struct Image { VkImage image; VkDeviceMemory memory; VkImageView view; VkImageAspectFlags aspect; };
        auto makeImage = [&](VkFormat format, VkImageUsageFlags usage, VkImageAspectFlags aspect) {
            Image im{VK_NULL_HANDLE, VK_NULL_HANDLE, VK_NULL_HANDLE, aspect};
            const VkImageCreateInfo info{VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO, nullptr, 0, VK_IMAGE_TYPE_2D, format, {size.width, size.height, 1}, 1, 1,
                                         VK_SAMPLE_COUNT_1_BIT, VK_IMAGE_TILING_OPTIMAL, usage, VK_SHARING_MODE_EXCLUSIVE, 0, nullptr, VK_IMAGE_LAYOUT_UNDEFINED};
            DISPMAP_VK_CHECK(fn, vkCreateImage, device, &info, nullptr, &im.image);
            VkMemoryRequirements needs{};
            fn.vkGetImageMemoryRequirements(device, im.image, &needs);
            const VkMemoryAllocateInfo alloc{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO, nullptr, needs.size,
                                             ctx.findMemoryType(needs.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT)};
            DISPMAP_VK_CHECK(fn, vkAllocateMemory, device, &alloc, nullptr, &im.memory);
            DISPMAP_VK_CHECK(fn, vkBindImageMemory, device, im.image, im.memory, 0);
            const VkImageViewCreateInfo view{VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO, nullptr, 0, im.image, VK_IMAGE_VIEW_TYPE_2D, format, {}, {aspect, 0, 1, 0, 1}};
            DISPMAP_VK_CHECK(fn, vkCreateImageView, device, &view, nullptr, &im.view);
            return im;
        };
        const Image color = makeImage(VK_FORMAT_B8G8R8A8_UNORM, VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT, VK_IMAGE_ASPECT_COLOR_BIT);
        const Image depth = makeImage(VK_FORMAT_D32_SFLOAT, VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT, VK_IMAGE_ASPECT_DEPTH_BIT);
        dv::Buffer pixels(ctx, VkDeviceSize{size.width} * size.height * 4);
        VkCommandPool pool = VK_NULL_HANDLE;
        VkCommandBuffer cmd = VK_NULL_HANDLE;
        VkFence fence = VK_NULL_HANDLE;
        const VkCommandPoolCreateInfo poolInfo{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO, nullptr, 0, ctx.queueFamily()};
        DISPMAP_VK_CHECK(fn, vkCreateCommandPool, device, &poolInfo, nullptr, &pool);
        const VkCommandBufferAllocateInfo cmdInfo{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO, nullptr, pool, VK_COMMAND_BUFFER_LEVEL_PRIMARY, 1};
        DISPMAP_VK_CHECK(fn, vkAllocateCommandBuffers, device, &cmdInfo, &cmd);
        const VkFenceCreateInfo fenceInfo{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO, nullptr, 0};
        DISPMAP_VK_CHECK(fn, vkCreateFence, device, &fenceInfo, nullptr, &fence);
        auto barrier = [&](const Image& im, VkImageLayout from, VkImageLayout to, VkPipelineStageFlags srcStage, VkAccessFlags src,
                           VkPipelineStageFlags dstStage, VkAccessFlags dst) {
            const VkImageMemoryBarrier b{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER, nullptr, src, dst, from, to, VK_QUEUE_FAMILY_IGNORED,
                                         VK_QUEUE_FAMILY_IGNORED, im.image, {im.aspect, 0, 1, 0, 1}};
            fn.vkCmdPipelineBarrier(cmd, srcStage, dstStage, 0, 0, nullptr, 0, nullptr, 1, &b);
        };

        // One frame: the renderer's update (outside rendering), our rendering with its draw, a copy.
        const VkCommandBufferBeginInfo begin{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO, nullptr, VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT, nullptr};
        DISPMAP_VK_CHECK(fn, vkBeginCommandBuffer, cmd, &begin);
        renderer.recordUpdate(cmd);
        barrier(color, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, 0,
                VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT, VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT);
        barrier(depth, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, 0,
                VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT, VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_READ_BIT | VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT);
        auto attachment = [](VkImageView view, VkImageLayout layout, VkClearValue clear, VkAttachmentStoreOp store) {
            VkRenderingAttachmentInfo a{};
            a.sType = VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO;
            a.imageView = view;
            a.imageLayout = layout;
            a.loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
            a.storeOp = store;
            a.clearValue = clear;
            return a;
        };
        VkClearValue background{}, far{}; // depth: 0 near, 1 far, compare LESS
        background.color = {{0.1f, 0.12f, 0.16f, 1.0f}};
        far.depthStencil = {1.0f, 0};
        const VkRenderingAttachmentInfo colorAttachment = attachment(color.view, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, background, VK_ATTACHMENT_STORE_OP_STORE);
        const VkRenderingAttachmentInfo depthAttachment = attachment(depth.view, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL, far, VK_ATTACHMENT_STORE_OP_DONT_CARE);
        const VkRenderingInfo rendering{VK_STRUCTURE_TYPE_RENDERING_INFO, nullptr, 0, {{0, 0}, size}, 1, 0, 1, &colorAttachment, &depthAttachment, nullptr};
        fn.vkCmdBeginRendering(cmd, &rendering);
        renderer.recordDraw(cmd);
        fn.vkCmdEndRendering(cmd);
        barrier(color, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT,
                VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT);
        const VkBufferImageCopy region{0, 0, 0, {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1}, {0, 0, 0}, {size.width, size.height, 1}};
        fn.vkCmdCopyImageToBuffer(cmd, color.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, pixels.handle(), 1, &region);
        const VkMemoryBarrier toHost{VK_STRUCTURE_TYPE_MEMORY_BARRIER, nullptr, VK_ACCESS_TRANSFER_WRITE_BIT, VK_ACCESS_HOST_READ_BIT};
        fn.vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &toHost, 0, nullptr, 0, nullptr);
        DISPMAP_VK_CHECK(fn, vkEndCommandBuffer, cmd);
        const VkSubmitInfo submit{VK_STRUCTURE_TYPE_SUBMIT_INFO, nullptr, 0, nullptr, nullptr, 1, &cmd, 0, nullptr};
        DISPMAP_VK_CHECK(fn, vkQueueSubmit, ctx.queue(), 1, &submit, fence);
        DISPMAP_VK_CHECK(fn, vkWaitForFences, device, 1, &fence, VK_TRUE, UINT64_MAX);

        std::vector<std::uint8_t> rgba(pixels.size());
        pixels.download(rgba.data(), rgba.size());
        for (std::size_t i = 0; i < rgba.size(); i += 4) std::swap(rgba[i], rgba[i + 2]); // BGRA -> RGBA
        dispmap::writeRgbaPng(out, draw.width, draw.height, rgba.data());
        fn.vkDestroyFence(device, fence, nullptr);
        fn.vkDestroyCommandPool(device, pool, nullptr);
        for (const Image& im : {color, depth}) {
            fn.vkDestroyImageView(device, im.view, nullptr);
            fn.vkDestroyImage(device, im.image, nullptr);
            fn.vkFreeMemory(device, im.memory, nullptr);
        }
        // With DISPMAP_VK_VALIDATION=1 the validation layer runs; any message is a failure.
        const std::vector<std::string> messages = ctx.takeValidationMessages();
        for (const std::string& m : messages) std::fprintf(stderr, "validation: %s\n", m.c_str());
        if (!messages.empty()) return 1;
        std::printf("%s: drew %d Ptex faces at %d x %d into our own B8G8R8A8 image (our command buffer, vkCmdBeginRendering), wrote %s\n",
                    ctx.deviceName().c_str(), base.faceCount(), draw.width, draw.height, out.c_str());
        return 0;
    } catch (const dispmap::Error& e) {
        std::fprintf(stderr, "error: %s\n", e.what());
        return 1;
    }
}
