// Mesostructure scenes in the viewer (viewer.h): MesoRenderer renders offscreen on the viewer's
// device (dispmap has no swapchain path for them), the image is copied into a host-visible
// staging buffer and from there into the acquired swapchain image (vkCmdCopyBufferToImage).
// It is rendered again only when the camera or the window size changes.
#include <cstring>

#include "viewer.h"

namespace viewer {

void Viewer::renderMesoImage() {
    presenter_->waitIdle(); // the staging buffer may be read by a frame in flight
    const VkExtent2D extent = presenter_->extent();
    dispmap::vulkan::MesoRenderOptions o = mesoGpu_.options;
    o.width = static_cast<int>(extent.width);
    o.height = static_cast<int>(extent.height);
    o.camera.eye = orbitMoved_ ? orbit_.eye() : mesoScene_.eye;
    o.frames = 1;
    o.warmup = 0;
    const dispmap::vulkan::MesoImage im = dispmap::vulkan::renderMeso(*context_, mesoGpu_.parts, o);
    mesoRgba_ = im.rgba;
    stats_.gpuMs = im.gpuMs;
    stats_.valid = true;

    const VkDeviceSize bytes = VkDeviceSize{extent.width} * extent.height * 4;
    const Vk& vk = app_->vk();
    if (bytes != stagingSize_) {
        if (staging_) vk.vkDestroyBuffer(app_->device(), staging_, nullptr);
        if (stagingMemory_) vk.vkFreeMemory(app_->device(), stagingMemory_, nullptr);
        staging_ = VK_NULL_HANDLE;
        stagingMemory_ = VK_NULL_HANDLE;
        VkBufferCreateInfo bi{};
        bi.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO;
        bi.size = bytes;
        bi.usage = VK_BUFFER_USAGE_TRANSFER_SRC_BIT;
        VIEWER_CHECK(vk.vkCreateBuffer(app_->device(), &bi, nullptr, &staging_));
        VkMemoryRequirements req{};
        vk.vkGetBufferMemoryRequirements(app_->device(), staging_, &req);
        VkMemoryAllocateInfo mi{};
        mi.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
        mi.allocationSize = req.size;
        mi.memoryTypeIndex = app_->memoryType(req.memoryTypeBits, VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
        VIEWER_CHECK(vk.vkAllocateMemory(app_->device(), &mi, nullptr, &stagingMemory_));
        VIEWER_CHECK(vk.vkBindBufferMemory(app_->device(), staging_, stagingMemory_, 0));
        VIEWER_CHECK(vk.vkMapMemory(app_->device(), stagingMemory_, 0, VK_WHOLE_SIZE, 0, &stagingMapped_));
        stagingSize_ = bytes;
    }
    auto* dst = static_cast<std::uint8_t*>(stagingMapped_);
    std::memcpy(dst, mesoRgba_.data(), static_cast<std::size_t>(bytes));
    if (presenter_->colorFormat() == VK_FORMAT_B8G8R8A8_UNORM)
        for (std::size_t i = 0; i < static_cast<std::size_t>(bytes); i += 4) std::swap(dst[i], dst[i + 2]);
    mesoDirty_ = false;
    generation_ = presenter_->generation();
}

void Viewer::drawMesoFrame(bool screenshot) {
    if (mesoDirty_ || generation_ != presenter_->generation()) renderMesoImage();
    presenter_->copyFromBuffer(staging_);
    presenter_->end(screenshot);
}

} // namespace viewer
