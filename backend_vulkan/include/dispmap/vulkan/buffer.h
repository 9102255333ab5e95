#pragma once
// dispmap::vulkan::Buffer: a host-visible, host-coherent storage buffer, mapped for its lifetime.
#include <cstddef>
#include <span>

#include "dispmap/vulkan/context.h"

namespace dispmap::vulkan {

/// A storage buffer (also a transfer source and destination) in HOST_VISIBLE | HOST_COHERENT
/// memory, persistently mapped: writes through data() are seen by the next submission, and shader
/// writes are seen after Context::dispatch returns. Move-only; must not outlive its Context.
class Buffer {
  public:
    /// ArgumentError if bytes is 0; VulkanError if the allocation fails.
    Buffer(Context& context, VkDeviceSize bytes);
    ~Buffer();
    Buffer(Buffer&& other) noexcept;
    Buffer& operator=(Buffer&& other) noexcept;
    Buffer(const Buffer&) = delete;
    Buffer& operator=(const Buffer&) = delete;

    VkBuffer handle() const { return buffer_; }
    VkDeviceSize size() const { return size_; }
    void* data() const { return mapped_; }
    /// The mapped bytes as size() / sizeof(T) elements of T (trailing bytes ignored).
    template <class T> std::span<T> as() const {
        return {static_cast<T*>(mapped_), static_cast<std::size_t>(size_ / sizeof(T))};
    }

    /// Copies bytes from src to [offset, offset + bytes); ArgumentError if that is past the end.
    void upload(const void* src, std::size_t bytes, std::size_t offset = 0);
    /// Copies [offset, offset + bytes) to dst; ArgumentError if that is past the end.
    void download(void* dst, std::size_t bytes, std::size_t offset = 0) const;

  private:
    void release() noexcept;
    void checkRange(std::size_t bytes, std::size_t offset, const char* what) const;

    Context* context_ = nullptr;
    VkBuffer buffer_ = VK_NULL_HANDLE;
    VkDeviceMemory memory_ = VK_NULL_HANDLE;
    VkDeviceSize size_ = 0;
    void* mapped_ = nullptr;
};

} // namespace dispmap::vulkan
