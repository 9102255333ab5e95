// The swapchain and the frames in flight (presenter.h).
#include "presenter.h"

#include <algorithm>
#include <cstring>

namespace viewer {

using dispmap::vulkan::VulkanError;

namespace {
// The stages that wait for the acquire semaphore: drawing, or copying an image in.
constexpr VkPipelineStageFlags kAcquireStages = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT;
constexpr VkQueryPipelineStatisticFlags kStatistics =
    VK_QUERY_PIPELINE_STATISTIC_TESSELLATION_CONTROL_SHADER_PATCHES_BIT | VK_QUERY_PIPELINE_STATISTIC_CLIPPING_INVOCATIONS_BIT;
} // namespace

Presenter::Presenter(VulkanApp& app, GLFWwindow* window) : app_(app), window_(window) {
    const Vk& vk = app_.vk();
    try {
        VkCommandPoolCreateInfo pi{};
        pi.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO;
        pi.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
        pi.queueFamilyIndex = app_.queueFamily();
        VIEWER_CHECK(vk.vkCreateCommandPool(app_.device(), &pi, nullptr, &pool_));
        std::uint32_t fc = 0;
        app_.vk().vkGetPhysicalDeviceQueueFamilyProperties(app_.physicalDevice(), &fc, nullptr);
        std::vector<VkQueueFamilyProperties> families(fc);
        app_.vk().vkGetPhysicalDeviceQueueFamilyProperties(app_.physicalDevice(), &fc, families.data());
        timestamps_ = families[app_.queueFamily()].timestampValidBits > 0 && app_.properties().limits.timestampPeriod > 0;
        timestampNs_ = static_cast<double>(app_.properties().limits.timestampPeriod);
        for (Slot& s : slots_) {
            VkCommandBufferAllocateInfo ai{};
            ai.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO;
            ai.commandPool = pool_;
            ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
            ai.commandBufferCount = 1;
            VIEWER_CHECK(vk.vkAllocateCommandBuffers(app_.device(), &ai, &s.cmd));
            VkFenceCreateInfo fi{};
            fi.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO;
            fi.flags = VK_FENCE_CREATE_SIGNALED_BIT;
            VIEWER_CHECK(vk.vkCreateFence(app_.device(), &fi, nullptr, &s.fence));
            VkSemaphoreCreateInfo si{};
            si.sType = VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO;
            VIEWER_CHECK(vk.vkCreateSemaphore(app_.device(), &si, nullptr, &s.acquired));
            if (app_.statisticsQueries()) {
                VkQueryPoolCreateInfo qi{};
                qi.sType = VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO;
                qi.queryType = VK_QUERY_TYPE_PIPELINE_STATISTICS;
                qi.queryCount = 1;
                qi.pipelineStatistics = kStatistics;
                VIEWER_CHECK(vk.vkCreateQueryPool(app_.device(), &qi, nullptr, &s.statistics));
            }
            if (timestamps_) {
                VkQueryPoolCreateInfo qi{};
                qi.sType = VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO;
                qi.queryType = VK_QUERY_TYPE_TIMESTAMP;
                qi.queryCount = 2;
                VIEWER_CHECK(vk.vkCreateQueryPool(app_.device(), &qi, nullptr, &s.timestamps));
            }
        }
        createSwapchain();
    } catch (...) {
        destroy();
        throw;
    }
}

Presenter::~Presenter() { destroy(); }

void Presenter::waitIdle() {
    if (app_.device()) app_.vk().vkDeviceWaitIdle(app_.device());
}

void Presenter::destroy() noexcept {
    const Vk& vk = app_.vk();
    waitIdle();
    destroySwapchain();
    for (Slot& s : slots_) {
        if (s.statistics) vk.vkDestroyQueryPool(app_.device(), s.statistics, nullptr);
        if (s.timestamps) vk.vkDestroyQueryPool(app_.device(), s.timestamps, nullptr);
        if (s.acquired) vk.vkDestroySemaphore(app_.device(), s.acquired, nullptr);
        if (s.fence) vk.vkDestroyFence(app_.device(), s.fence, nullptr);
        s = Slot{};
    }
    if (pool_) vk.vkDestroyCommandPool(app_.device(), pool_, nullptr);
    pool_ = VK_NULL_HANDLE;
}

void Presenter::destroySwapchain() noexcept {
    const Vk& vk = app_.vk();
    const VkDevice d = app_.device();
    if (readback_) vk.vkDestroyBuffer(d, readback_, nullptr);
    if (readbackMemory_) vk.vkFreeMemory(d, readbackMemory_, nullptr);
    if (depthView_) vk.vkDestroyImageView(d, depthView_, nullptr);
    if (depth_) vk.vkDestroyImage(d, depth_, nullptr);
    if (depthMemory_) vk.vkFreeMemory(d, depthMemory_, nullptr);
    for (VkSemaphore s : rendered_) vk.vkDestroySemaphore(d, s, nullptr);
    for (VkImageView v : views_) vk.vkDestroyImageView(d, v, nullptr);
    if (swapchain_) vk.vkDestroySwapchainKHR(d, swapchain_, nullptr);
    readback_ = VK_NULL_HANDLE;
    readbackMemory_ = VK_NULL_HANDLE;
    depthView_ = VK_NULL_HANDLE;
    depth_ = VK_NULL_HANDLE;
    depthMemory_ = VK_NULL_HANDLE;
    rendered_.clear();
    views_.clear();
    images_.clear();
    swapchain_ = VK_NULL_HANDLE;
    haveScreenshot_ = false;
}

void Presenter::createSwapchain() {
    const Vk& vk = app_.vk();
    const VkDevice d = app_.device();
    VkSurfaceCapabilitiesKHR caps{};
    VIEWER_CHECK(vk.vkGetPhysicalDeviceSurfaceCapabilitiesKHR(app_.physicalDevice(), app_.surface(), &caps));
    std::uint32_t n = 0;
    VIEWER_CHECK(vk.vkGetPhysicalDeviceSurfaceFormatsKHR(app_.physicalDevice(), app_.surface(), &n, nullptr));
    std::vector<VkSurfaceFormatKHR> formats(n);
    VIEWER_CHECK(vk.vkGetPhysicalDeviceSurfaceFormatsKHR(app_.physicalDevice(), app_.surface(), &n, formats.data()));
    if (n == 0) throw VulkanError("the window surface offers no formats");
    // UNORM as the offscreen renderer writes it (8-bit values, no sRGB encoding), BGRA first.
    VkSurfaceFormatKHR chosen = formats[0];
    for (VkFormat want : {VK_FORMAT_B8G8R8A8_UNORM, VK_FORMAT_R8G8B8A8_UNORM}) {
        const auto it = std::find_if(formats.begin(), formats.end(), [&](const VkSurfaceFormatKHR& f) { return f.format == want; });
        if (it != formats.end()) {
            chosen = *it;
            break;
        }
    }
    if (chosen.format != VK_FORMAT_B8G8R8A8_UNORM && chosen.format != VK_FORMAT_R8G8B8A8_UNORM)
        throw VulkanError("the window surface offers neither B8G8R8A8_UNORM nor R8G8B8A8_UNORM");
    format_ = chosen.format;

    if (caps.currentExtent.width != 0xFFFFFFFFu) {
        extent_ = caps.currentExtent;
    } else {
        int w = 0, h = 0;
        glfwGetFramebufferSize(window_, &w, &h);
        extent_ = {std::clamp(static_cast<std::uint32_t>(w), caps.minImageExtent.width, caps.maxImageExtent.width),
                   std::clamp(static_cast<std::uint32_t>(h), caps.minImageExtent.height, caps.maxImageExtent.height)};
    }
    const VkImageUsageFlags usage = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT;
    if ((caps.supportedUsageFlags & usage) != usage)
        throw VulkanError("the swapchain images cannot be colour attachments and transfer sources/destinations (screenshots, "
                          "mesostructure images)");
    std::uint32_t count = std::max(caps.minImageCount + 1, 3u);
    if (caps.maxImageCount > 0) count = std::min(count, caps.maxImageCount);

    VkSwapchainCreateInfoKHR si{};
    si.sType = VK_STRUCTURE_TYPE_SWAPCHAIN_CREATE_INFO_KHR;
    si.surface = app_.surface();
    si.minImageCount = count;
    si.imageFormat = chosen.format;
    si.imageColorSpace = chosen.colorSpace;
    si.imageExtent = extent_;
    si.imageArrayLayers = 1;
    si.imageUsage = usage;
    si.imageSharingMode = VK_SHARING_MODE_EXCLUSIVE;
    si.preTransform = caps.currentTransform;
    si.compositeAlpha = (caps.supportedCompositeAlpha & VK_COMPOSITE_ALPHA_OPAQUE_BIT_KHR) ? VK_COMPOSITE_ALPHA_OPAQUE_BIT_KHR
                                                                                             : VK_COMPOSITE_ALPHA_INHERIT_BIT_KHR;
    si.presentMode = VK_PRESENT_MODE_FIFO_KHR; // always supported
    si.clipped = VK_TRUE;
    VIEWER_CHECK(vk.vkCreateSwapchainKHR(d, &si, nullptr, &swapchain_));
    VIEWER_CHECK(vk.vkGetSwapchainImagesKHR(d, swapchain_, &n, nullptr));
    images_.resize(n);
    VIEWER_CHECK(vk.vkGetSwapchainImagesKHR(d, swapchain_, &n, images_.data()));
    for (VkImage image : images_) {
        VkImageViewCreateInfo vi{};
        vi.sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO;
        vi.image = image;
        vi.viewType = VK_IMAGE_VIEW_TYPE_2D;
        vi.format = format_;
        vi.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
        VIEWER_CHECK(vk.vkCreateImageView(d, &vi, nullptr, &views_.emplace_back()));
        VkSemaphoreCreateInfo sem{};
        sem.sType = VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO;
        VIEWER_CHECK(vk.vkCreateSemaphore(d, &sem, nullptr, &rendered_.emplace_back()));
    }

    // One depth image: the frames in flight take turns on it, ordered by a barrier.
    VkImageCreateInfo ii{};
    ii.sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO;
    ii.imageType = VK_IMAGE_TYPE_2D;
    ii.format = kDepthFormat;
    ii.extent = {extent_.width, extent_.height, 1};
    ii.mipLevels = 1;
    ii.arrayLayers = 1;
    ii.samples = VK_SAMPLE_COUNT_1_BIT;
    ii.tiling = VK_IMAGE_TILING_OPTIMAL;
    ii.usage = VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT;
    ii.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
    VIEWER_CHECK(vk.vkCreateImage(d, &ii, nullptr, &depth_));
    VkMemoryRequirements req{};
    vk.vkGetImageMemoryRequirements(d, depth_, &req);
    VkMemoryAllocateInfo mi{};
    mi.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
    mi.allocationSize = req.size;
    mi.memoryTypeIndex = app_.memoryType(req.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
    VIEWER_CHECK(vk.vkAllocateMemory(d, &mi, nullptr, &depthMemory_));
    VIEWER_CHECK(vk.vkBindImageMemory(d, depth_, depthMemory_, 0));
    VkImageViewCreateInfo dv{};
    dv.sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO;
    dv.image = depth_;
    dv.viewType = VK_IMAGE_VIEW_TYPE_2D;
    dv.format = kDepthFormat;
    dv.subresourceRange = {VK_IMAGE_ASPECT_DEPTH_BIT, 0, 1, 0, 1};
    VIEWER_CHECK(vk.vkCreateImageView(d, &dv, nullptr, &depthView_));

    // The screenshot buffer.
    VkBufferCreateInfo bi{};
    bi.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO;
    bi.size = VkDeviceSize{extent_.width} * extent_.height * 4;
    bi.usage = VK_BUFFER_USAGE_TRANSFER_DST_BIT;
    bi.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
    VIEWER_CHECK(vk.vkCreateBuffer(d, &bi, nullptr, &readback_));
    vk.vkGetBufferMemoryRequirements(d, readback_, &req);
    mi.allocationSize = req.size;
    mi.memoryTypeIndex =
        app_.memoryType(req.memoryTypeBits, VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
    VIEWER_CHECK(vk.vkAllocateMemory(d, &mi, nullptr, &readbackMemory_));
    VIEWER_CHECK(vk.vkBindBufferMemory(d, readback_, readbackMemory_, 0));
    ++generation_;
}

bool Presenter::begin() {
    const Vk& vk = app_.vk();
    const VkDevice d = app_.device();
    int w = 0, h = 0;
    glfwGetFramebufferSize(window_, &w, &h);
    if (w == 0 || h == 0) return false; // minimised
    if (stale_ || static_cast<std::uint32_t>(w) != extent_.width || static_cast<std::uint32_t>(h) != extent_.height) {
        stale_ = false;
        waitIdle();
        destroySwapchain();
        createSwapchain();
    }
    Slot& s = slots_[static_cast<std::size_t>(current_)];
    VIEWER_CHECK(vk.vkWaitForFences(d, 1, &s.fence, VK_TRUE, UINT64_MAX));

    // What this slot measured last time (its fence has signalled, so the results are there).
    frame_.previous = FrameStats{};
    if (s.queried) {
        // In the order of the flag bits: clipping invocations (0x80), then control shader patches (0x100).
        std::uint64_t r[2] = {0, 0};
        VIEWER_CHECK(vk.vkGetQueryPoolResults(d, s.statistics, 0, 1, sizeof r, r, sizeof r, VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT));
        frame_.previous.valid = true;
        frame_.previous.triangles = r[0];
        frame_.previous.patches = r[1];
    }
    if (s.timed) {
        std::uint64_t t[2] = {0, 0};
        VIEWER_CHECK(vk.vkGetQueryPoolResults(d, s.timestamps, 0, 2, sizeof t, t, sizeof t[0], VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT));
        frame_.previous.valid = true;
        frame_.previous.gpuMs = static_cast<double>(t[1] - t[0]) * timestampNs_ * 1e-6;
    }
    s.queried = s.timed = false;

    for (int attempt = 0;; ++attempt) {
        const VkResult r = vk.vkAcquireNextImageKHR(d, swapchain_, UINT64_MAX, s.acquired, VK_NULL_HANDLE, &frame_.imageIndex);
        if (r == VK_SUCCESS || r == VK_SUBOPTIMAL_KHR) break;
        if (r != VK_ERROR_OUT_OF_DATE_KHR || attempt > 2) VIEWER_CHECK(r);
        waitIdle();
        destroySwapchain();
        createSwapchain();
    }
    VIEWER_CHECK(vk.vkResetFences(d, 1, &s.fence));
    VIEWER_CHECK(vk.vkResetCommandBuffer(s.cmd, 0));
    VkCommandBufferBeginInfo bi{};
    bi.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO;
    bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    VIEWER_CHECK(vk.vkBeginCommandBuffer(s.cmd, &bi));
    frame_.cmd = s.cmd;
    frame_.image = images_[frame_.imageIndex];
    setState(VK_IMAGE_LAYOUT_UNDEFINED, kAcquireStages, 0);
    return true;
}

void Presenter::barrier(VkImage image, VkImageAspectFlags aspect, VkImageLayout from, VkImageLayout to, VkPipelineStageFlags srcStage,
                        VkAccessFlags srcAccess, VkPipelineStageFlags dstStage, VkAccessFlags dstAccess) const {
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
    app_.vk().vkCmdPipelineBarrier(frame_.cmd, srcStage, dstStage, 0, 0, nullptr, 0, nullptr, 1, &b);
}

void Presenter::beginRendering(const glm::dvec3& clear, bool withQueries) {
    const Vk& vk = app_.vk();
    Slot& s = slots_[static_cast<std::size_t>(current_)];
    if (withQueries && s.statistics) vk.vkCmdResetQueryPool(frame_.cmd, s.statistics, 0, 1);
    if (withQueries && s.timestamps) vk.vkCmdResetQueryPool(frame_.cmd, s.timestamps, 0, 2);
    barrier(frame_.image, VK_IMAGE_ASPECT_COLOR_BIT, layout_, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, stage_, access_,
            VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT, VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT | VK_ACCESS_COLOR_ATTACHMENT_READ_BIT);
    // The other frame in flight may still be testing against the depth image: wait for its tests.
    constexpr VkPipelineStageFlags tests = VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT;
    barrier(depth_, VK_IMAGE_ASPECT_DEPTH_BIT, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL, tests,
            VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT, tests,
            VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_READ_BIT | VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT);
    setState(VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT,
                         VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT);

    VkRenderingAttachmentInfo color{};
    color.sType = VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO;
    color.imageView = views_[frame_.imageIndex];
    color.imageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
    color.loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
    color.storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    color.clearValue.color = {{static_cast<float>(clear.r), static_cast<float>(clear.g), static_cast<float>(clear.b), 1.0f}};
    VkRenderingAttachmentInfo depth{};
    depth.sType = VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO;
    depth.imageView = depthView_;
    depth.imageLayout = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL;
    depth.loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
    depth.storeOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
    depth.clearValue.depthStencil = {1.0f, 0};
    VkRenderingInfo ri{};
    ri.sType = VK_STRUCTURE_TYPE_RENDERING_INFO;
    ri.renderArea = {{0, 0}, extent_};
    ri.layerCount = 1;
    ri.colorAttachmentCount = 1;
    ri.pColorAttachments = &color;
    ri.pDepthAttachment = &depth;
    if (withQueries && s.timestamps) {
        vk.vkCmdWriteTimestamp(frame_.cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, s.timestamps, 0);
        s.timed = true;
    }
    vk.vkCmdBeginRendering(frame_.cmd, &ri);
    if (withQueries && s.statistics) {
        vk.vkCmdBeginQuery(frame_.cmd, s.statistics, 0, 0);
        s.queried = true;
    }
}

void Presenter::endRendering() {
    const Vk& vk = app_.vk();
    Slot& s = slots_[static_cast<std::size_t>(current_)];
    if (s.queried) vk.vkCmdEndQuery(frame_.cmd, s.statistics, 0);
    vk.vkCmdEndRendering(frame_.cmd);
    if (s.timed) vk.vkCmdWriteTimestamp(frame_.cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, s.timestamps, 1);
}

void Presenter::copyFromBuffer(VkBuffer buffer) {
    barrier(frame_.image, VK_IMAGE_ASPECT_COLOR_BIT, layout_, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, stage_, access_,
            VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT);
    VkBufferImageCopy c{};
    c.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    c.imageExtent = {extent_.width, extent_.height, 1};
    app_.vk().vkCmdCopyBufferToImage(frame_.cmd, buffer, frame_.image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &c);
    setState(VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT);
}

void Presenter::end(bool screenshot) {
    const Vk& vk = app_.vk();
    Slot& s = slots_[static_cast<std::size_t>(current_)];
    if (screenshot) {
        barrier(frame_.image, VK_IMAGE_ASPECT_COLOR_BIT, layout_, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, stage_, access_,
                VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT);
        VkBufferImageCopy c{};
        c.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
        c.imageExtent = {extent_.width, extent_.height, 1};
        vk.vkCmdCopyImageToBuffer(frame_.cmd, frame_.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, readback_, 1, &c);
        // The copy's writes made visible to the host, which maps the buffer after the wait.
        VkMemoryBarrier toHost{};
        toHost.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
        toHost.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
        toHost.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
        vk.vkCmdPipelineBarrier(frame_.cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &toHost, 0, nullptr,
                                0, nullptr);
        setState(VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_PIPELINE_STAGE_TRANSFER_BIT, 0);
        haveScreenshot_ = true;
    }
    // To the presentation engine (the semaphore makes the writes available to it).
    barrier(frame_.image, VK_IMAGE_ASPECT_COLOR_BIT, layout_, VK_IMAGE_LAYOUT_PRESENT_SRC_KHR, stage_, access_,
            VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, 0);
    VIEWER_CHECK(vk.vkEndCommandBuffer(frame_.cmd));

    const VkPipelineStageFlags waitStage = kAcquireStages;
    VkSubmitInfo si{};
    si.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
    si.waitSemaphoreCount = 1;
    si.pWaitSemaphores = &s.acquired;
    si.pWaitDstStageMask = &waitStage;
    si.commandBufferCount = 1;
    si.pCommandBuffers = &frame_.cmd;
    si.signalSemaphoreCount = 1;
    si.pSignalSemaphores = &rendered_[frame_.imageIndex];
    VIEWER_CHECK(vk.vkQueueSubmit(app_.queue(), 1, &si, s.fence));

    VkPresentInfoKHR pi{};
    pi.sType = VK_STRUCTURE_TYPE_PRESENT_INFO_KHR;
    pi.waitSemaphoreCount = 1;
    pi.pWaitSemaphores = &rendered_[frame_.imageIndex];
    pi.swapchainCount = 1;
    pi.pSwapchains = &swapchain_;
    pi.pImageIndices = &frame_.imageIndex;
    const VkResult r = vk.vkQueuePresentKHR(app_.queue(), &pi);
    if (r == VK_ERROR_OUT_OF_DATE_KHR || r == VK_SUBOPTIMAL_KHR) {
        stale_ = true; // made again at the next begin()
    } else {
        VIEWER_CHECK(r);
    }
    current_ = (current_ + 1) % kFramesInFlight;
}

std::vector<std::uint8_t> Presenter::screenshot() {
    if (!haveScreenshot_) throw VulkanError("no screenshot was taken");
    waitIdle();
    const Vk& vk = app_.vk();
    void* mapped = nullptr;
    const std::size_t bytes = std::size_t{extent_.width} * extent_.height * 4;
    VIEWER_CHECK(vk.vkMapMemory(app_.device(), readbackMemory_, 0, VK_WHOLE_SIZE, 0, &mapped));
    std::vector<std::uint8_t> rgba(bytes);
    std::memcpy(rgba.data(), mapped, bytes);
    vk.vkUnmapMemory(app_.device(), readbackMemory_);
    if (format_ == VK_FORMAT_B8G8R8A8_UNORM)
        for (std::size_t i = 0; i < bytes; i += 4) std::swap(rgba[i], rgba[i + 2]);
    return rgba;
}

} // namespace viewer
