// Buffers and images that own their memory (one allocation each: the renderer creates few, large
// resources, so a sub-allocator would buy nothing here). Move-only RAII.
#pragma once

#include "vk/context.hpp"

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace hp::vk {

class Buffer {
 public:
  Buffer() = default;
  /// `host_visible`: HOST_VISIBLE | HOST_COHERENT, persistently mapped; else DEVICE_LOCAL.
  Buffer(Context& ctx, VkDeviceSize size_bytes, VkBufferUsageFlags usage, bool host_visible);
  ~Buffer();
  Buffer(Buffer&& o) noexcept;
  Buffer& operator=(Buffer&& o) noexcept;
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;

  VkBuffer handle() const { return buffer_; }
  VkDeviceSize size() const { return size_; }
  void* mapped() const { return mapped_; }
  /// The buffer's device address (usage VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT), else 0.
  VkDeviceAddress device_address() const { return address_; }
  explicit operator bool() const { return buffer_ != VK_NULL_HANDLE; }

 private:
  void reset();
  VkDevice device_ = VK_NULL_HANDLE;
  VkBuffer buffer_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  VkDeviceSize size_ = 0;
  void* mapped_ = nullptr;
  VkDeviceAddress address_ = 0;
};

/// A texel view of a whole buffer (VK_WHOLE_SIZE), for uniform texel buffer descriptors.
class BufferView {
 public:
  BufferView() = default;
  BufferView(Context& ctx, const Buffer& buffer, VkFormat format);
  ~BufferView();
  BufferView(BufferView&& o) noexcept;
  BufferView& operator=(BufferView&& o) noexcept;
  BufferView(const BufferView&) = delete;
  BufferView& operator=(const BufferView&) = delete;
  VkBufferView handle() const { return view_; }

 private:
  VkDevice device_ = VK_NULL_HANDLE;
  VkBufferView view_ = VK_NULL_HANDLE;
};

class Image {
 public:
  Image() = default;
  Image(Context& ctx, uint32_t width, uint32_t height, VkFormat format, VkImageUsageFlags usage);
  ~Image();
  Image(Image&& o) noexcept;
  Image& operator=(Image&& o) noexcept;
  Image(const Image&) = delete;
  Image& operator=(const Image&) = delete;

  VkImage handle() const { return image_; }
  VkImageView view() const { return view_; }
  VkFormat format() const { return format_; }
  uint32_t width() const { return width_; }
  uint32_t height() const { return height_; }
  VkImageAspectFlags aspect() const { return aspect_; }

 private:
  void reset();
  VkDevice device_ = VK_NULL_HANDLE;
  VkImage image_ = VK_NULL_HANDLE;
  VkImageView view_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  VkFormat format_ = VK_FORMAT_UNDEFINED;
  VkImageAspectFlags aspect_ = 0;
  uint32_t width_ = 0, height_ = 0;
};

/// Bytes per texel of the formats the renderer uses.
uint32_t format_size_bytes(VkFormat format);

/// A device-local buffer filled with `data` through a staging buffer.
Buffer upload_buffer(Context& ctx, std::span<const std::byte> data, VkBufferUsageFlags usage);
template <typename T>
Buffer upload_vector(Context& ctx, const std::vector<T>& v, VkBufferUsageFlags usage) {
  return upload_buffer(ctx, std::as_bytes(std::span<const T>(v)), usage);
}

/// Copies a whole device buffer back to the host.
std::vector<std::byte> read_buffer(Context& ctx, const Buffer& buffer);

/// Copies an image (currently in `layout`, left in that layout) to tightly packed host memory.
std::vector<std::byte> read_image(Context& ctx, const Image& image, VkImageLayout layout);

/// A full-subresource image layout transition (synchronization2), conservative stage/access masks.
void transition(VkCommandBuffer cmd, const Image& image, VkImageLayout from, VkImageLayout to,
                VkPipelineStageFlags2 src_stage, VkAccessFlags2 src_access, VkPipelineStageFlags2 dst_stage,
                VkAccessFlags2 dst_access);

/// A global memory barrier (synchronization2).
void memory_barrier(VkCommandBuffer cmd, VkPipelineStageFlags2 src_stage, VkAccessFlags2 src_access,
                    VkPipelineStageFlags2 dst_stage, VkAccessFlags2 dst_access);

}  // namespace hp::vk
