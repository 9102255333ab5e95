// Host-visible storage buffers: creation, mapping, range-checked upload and download.
#include "dispmap/vulkan/buffer.h"

#include <cstring>
#include <string>
#include <utility>

namespace dispmap::vulkan {

Buffer::Buffer(Context& context, VkDeviceSize bytes) : context_(&context), size_(bytes) {
    if (bytes == 0) throw ArgumentError("Vulkan buffer of size 0");
    const Functions& fn = context.fn();
    const VkDevice device = context.device();
    try {
        VkBufferCreateInfo info{};
        info.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO;
        info.size = bytes;
        info.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT |
                     VK_BUFFER_USAGE_TRANSFER_DST_BIT;
        info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
        DISPMAP_VK_CHECK(fn, vkCreateBuffer, device, &info, nullptr, &buffer_);
        VkMemoryRequirements needs{};
        fn.vkGetBufferMemoryRequirements(device, buffer_, &needs);
        VkMemoryAllocateInfo allocation{};
        allocation.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
        allocation.allocationSize = needs.size;
        allocation.memoryTypeIndex = context.findMemoryType(
            needs.memoryTypeBits, VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
        DISPMAP_VK_CHECK(fn, vkAllocateMemory, device, &allocation, nullptr, &memory_);
        DISPMAP_VK_CHECK(fn, vkBindBufferMemory, device, buffer_, memory_, 0);
        DISPMAP_VK_CHECK(fn, vkMapMemory, device, memory_, 0, VK_WHOLE_SIZE, 0, &mapped_);
    } catch (...) {
        release();
        throw;
    }
}

Buffer::~Buffer() {
    release();
}

Buffer::Buffer(Buffer&& other) noexcept
    : context_(std::exchange(other.context_, nullptr)), buffer_(std::exchange(other.buffer_, VK_NULL_HANDLE)),
      memory_(std::exchange(other.memory_, VK_NULL_HANDLE)), size_(std::exchange(other.size_, 0)),
      mapped_(std::exchange(other.mapped_, nullptr)) {}

Buffer& Buffer::operator=(Buffer&& other) noexcept {
    if (this != &other) {
        release();
        context_ = std::exchange(other.context_, nullptr);
        buffer_ = std::exchange(other.buffer_, VK_NULL_HANDLE);
        memory_ = std::exchange(other.memory_, VK_NULL_HANDLE);
        size_ = std::exchange(other.size_, 0);
        mapped_ = std::exchange(other.mapped_, nullptr);
    }
    return *this;
}

void Buffer::release() noexcept {
    if (!context_) return;
    const Functions& fn = context_->fn();
    // Freeing the memory unmaps it.
    if (buffer_) fn.vkDestroyBuffer(context_->device(), buffer_, nullptr);
    if (memory_) fn.vkFreeMemory(context_->device(), memory_, nullptr);
    buffer_ = VK_NULL_HANDLE;
    memory_ = VK_NULL_HANDLE;
    mapped_ = nullptr;
    size_ = 0;
    context_ = nullptr;
}

void Buffer::checkRange(std::size_t bytes, std::size_t offset, const char* what) const {
    if (offset > size_ || bytes > size_ - offset)
        throw ArgumentError(std::string("Vulkan buffer ") + what + " of " + std::to_string(bytes) +
                            " bytes at offset " + std::to_string(offset) + " exceeds the buffer's " +
                            std::to_string(size_) + " bytes");
}

void Buffer::upload(const void* src, std::size_t bytes, std::size_t offset) {
    checkRange(bytes, offset, "upload");
    if (bytes > 0) std::memcpy(static_cast<unsigned char*>(mapped_) + offset, src, bytes);
}

void Buffer::download(void* dst, std::size_t bytes, std::size_t offset) const {
    checkRange(bytes, offset, "download");
    if (bytes > 0) std::memcpy(dst, static_cast<const unsigned char*>(mapped_) + offset, bytes);
}

} // namespace dispmap::vulkan
