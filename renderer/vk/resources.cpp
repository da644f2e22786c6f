#include "vk/resources.hpp"

#include "error.hpp"
#include "vk/check.hpp"

#include <cstring>
#include <utility>

namespace hp::vk {

namespace {

// Out of device or host memory while allocating or binding: it is the size asked for (a resolution, a scene)
// that does not fit this device, so an InputError naming it, not a missing device.
void check_fits(VkResult r, const std::string& what, VkDeviceSize bytes) {
  if (r != VK_ERROR_OUT_OF_DEVICE_MEMORY && r != VK_ERROR_OUT_OF_HOST_MEMORY) return;
  throw InputError(
      what + " (" + std::to_string((bytes + (1u << 20) - 1) >> 20) + " MiB) does not fit in the device's memory (" +
      (r == VK_ERROR_OUT_OF_DEVICE_MEMORY ? "VK_ERROR_OUT_OF_DEVICE_MEMORY" : "VK_ERROR_OUT_OF_HOST_MEMORY") +
      "); a smaller resolution or scene needs less");
}

}  // namespace

Buffer::Buffer(Context& ctx, VkDeviceSize size_bytes, VkBufferUsageFlags usage, bool host_visible)
    : device_(ctx.device()), size_(size_bytes) {
  VkBufferCreateInfo ci{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  ci.size = size_bytes == 0 ? 4 : size_bytes;  // a zero-sized buffer is invalid; keep bindings valid
  ci.usage = usage;
  ci.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  HP_VK(vkCreateBuffer(device_, &ci, nullptr, &buffer_));
  VkMemoryRequirements req;
  vkGetBufferMemoryRequirements(device_, buffer_, &req);
  VkMemoryAllocateInfo ai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  // A buffer whose address shaders or the acceleration-structure build read needs memory allocated for it.
  const bool addressed = (usage & VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT) != 0;
  VkMemoryAllocateFlagsInfo flags{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_FLAGS_INFO};
  flags.flags = VK_MEMORY_ALLOCATE_DEVICE_ADDRESS_BIT;
  if (addressed) ai.pNext = &flags;
  ai.allocationSize = req.size;
  ai.memoryTypeIndex = ctx.find_memory_type(req.memoryTypeBits, host_visible ? VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT |
                                                                                   VK_MEMORY_PROPERTY_HOST_COHERENT_BIT
                                                                             : VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
  VkResult r = vkAllocateMemory(device_, &ai, nullptr, &memory_);
  if (r != VK_SUCCESS) {
    reset();
    check_fits(r, "a buffer of " + std::to_string(size_bytes) + " bytes", req.size);
    HP_VK(r);
  }
  r = vkBindBufferMemory(device_, buffer_, memory_, 0);
  if (r != VK_SUCCESS) {
    reset();
    check_fits(r, "a buffer of " + std::to_string(size_bytes) + " bytes", req.size);
    HP_VK(r);
  }
  if (host_visible) HP_VK(vkMapMemory(device_, memory_, 0, VK_WHOLE_SIZE, 0, &mapped_));
  if (addressed) {
    VkBufferDeviceAddressInfo bi{VK_STRUCTURE_TYPE_BUFFER_DEVICE_ADDRESS_INFO};
    bi.buffer = buffer_;
    address_ = vkGetBufferDeviceAddress(device_, &bi);
  }
}

BufferView::BufferView(Context& ctx, const Buffer& buffer, VkFormat format) : device_(ctx.device()) {
  VkBufferViewCreateInfo vi{VK_STRUCTURE_TYPE_BUFFER_VIEW_CREATE_INFO};
  vi.buffer = buffer.handle();
  vi.format = format;
  vi.offset = 0;
  vi.range = VK_WHOLE_SIZE;
  HP_VK(vkCreateBufferView(device_, &vi, nullptr, &view_));
}

BufferView::~BufferView() {
  if (view_) vkDestroyBufferView(device_, view_, nullptr);
}

BufferView::BufferView(BufferView&& o) noexcept { *this = std::move(o); }

BufferView& BufferView::operator=(BufferView&& o) noexcept {
  if (this != &o) {
    if (view_) vkDestroyBufferView(device_, view_, nullptr);
    device_ = std::exchange(o.device_, VK_NULL_HANDLE);
    view_ = std::exchange(o.view_, VK_NULL_HANDLE);
  }
  return *this;
}

Buffer::~Buffer() { reset(); }

Buffer::Buffer(Buffer&& o) noexcept { *this = std::move(o); }

Buffer& Buffer::operator=(Buffer&& o) noexcept {
  if (this != &o) {
    reset();
    device_ = std::exchange(o.device_, VK_NULL_HANDLE);
    buffer_ = std::exchange(o.buffer_, VK_NULL_HANDLE);
    memory_ = std::exchange(o.memory_, VK_NULL_HANDLE);
    size_ = std::exchange(o.size_, 0);
    mapped_ = std::exchange(o.mapped_, nullptr);
    address_ = std::exchange(o.address_, 0);
  }
  return *this;
}

void Buffer::reset() {
  if (device_) {
    if (buffer_) vkDestroyBuffer(device_, buffer_, nullptr);
    if (memory_) vkFreeMemory(device_, memory_, nullptr);  // unmaps implicitly
  }
  buffer_ = VK_NULL_HANDLE;
  memory_ = VK_NULL_HANDLE;
  mapped_ = nullptr;
  address_ = 0;
  size_ = 0;
}

uint32_t format_size_bytes(VkFormat format) {
  switch (format) {
    case VK_FORMAT_R8G8B8A8_UNORM:
    case VK_FORMAT_R8G8B8A8_SRGB:
    case VK_FORMAT_D32_SFLOAT:
    case VK_FORMAT_R32_SFLOAT:
    case VK_FORMAT_R32_UINT: return 4;
    case VK_FORMAT_R16G16B16A16_SFLOAT:
    case VK_FORMAT_R32G32_SFLOAT: return 8;
    case VK_FORMAT_R32G32B32A32_SFLOAT: return 16;
    default: throw std::logic_error("format_size_bytes: unhandled VkFormat " + std::to_string(format));
  }
}

Image::Image(Context& ctx, uint32_t width, uint32_t height, VkFormat format, VkImageUsageFlags usage)
    : device_(ctx.device()), format_(format), width_(width), height_(height) {
  aspect_ = format == VK_FORMAT_D32_SFLOAT ? VK_IMAGE_ASPECT_DEPTH_BIT : VK_IMAGE_ASPECT_COLOR_BIT;
  VkImageCreateInfo ci{VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO};
  ci.imageType = VK_IMAGE_TYPE_2D;
  ci.format = format;
  ci.extent = {width, height, 1};
  ci.mipLevels = 1;
  ci.arrayLayers = 1;
  ci.samples = VK_SAMPLE_COUNT_1_BIT;
  ci.tiling = VK_IMAGE_TILING_OPTIMAL;
  ci.usage = usage;
  ci.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
  HP_VK(vkCreateImage(device_, &ci, nullptr, &image_));
  VkMemoryRequirements req;
  vkGetImageMemoryRequirements(device_, image_, &req);
  VkMemoryAllocateInfo ai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  ai.allocationSize = req.size;
  ai.memoryTypeIndex = ctx.find_memory_type(req.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
  const std::string what = "a " + std::to_string(width) + "x" + std::to_string(height) + " image";
  VkResult r = vkAllocateMemory(device_, &ai, nullptr, &memory_);
  if (r != VK_SUCCESS) {
    reset();
    check_fits(r, what, req.size);
    HP_VK(r);
  }
  r = vkBindImageMemory(device_, image_, memory_, 0);
  if (r != VK_SUCCESS) {
    reset();
    check_fits(r, what, req.size);
    HP_VK(r);
  }
  VkImageViewCreateInfo vi{VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO};
  vi.image = image_;
  vi.viewType = VK_IMAGE_VIEW_TYPE_2D;
  vi.format = format;
  vi.subresourceRange = {aspect_, 0, 1, 0, 1};
  HP_VK(vkCreateImageView(device_, &vi, nullptr, &view_));
}

Image::~Image() { reset(); }

Image::Image(Image&& o) noexcept { *this = std::move(o); }

Image& Image::operator=(Image&& o) noexcept {
  if (this != &o) {
    reset();
    device_ = std::exchange(o.device_, VK_NULL_HANDLE);
    image_ = std::exchange(o.image_, VK_NULL_HANDLE);
    view_ = std::exchange(o.view_, VK_NULL_HANDLE);
    memory_ = std::exchange(o.memory_, VK_NULL_HANDLE);
    format_ = o.format_;
    aspect_ = o.aspect_;
    width_ = o.width_;
    height_ = o.height_;
  }
  return *this;
}

void Image::reset() {
  if (device_) {
    if (view_) vkDestroyImageView(device_, view_, nullptr);
    if (image_) vkDestroyImage(device_, image_, nullptr);
    if (memory_) vkFreeMemory(device_, memory_, nullptr);
  }
  view_ = VK_NULL_HANDLE;
  image_ = VK_NULL_HANDLE;
  memory_ = VK_NULL_HANDLE;
}

Buffer upload_buffer(Context& ctx, std::span<const std::byte> data, VkBufferUsageFlags usage) {
  Buffer dst(ctx, data.size(), usage | VK_BUFFER_USAGE_TRANSFER_DST_BIT, false);
  if (data.empty()) return dst;
  Buffer staging(ctx, data.size(), VK_BUFFER_USAGE_TRANSFER_SRC_BIT, true);
  std::memcpy(staging.mapped(), data.data(), data.size());
  ctx.submit_and_wait([&](VkCommandBuffer cmd) {
    VkBufferCopy region{0, 0, data.size()};
    vkCmdCopyBuffer(cmd, staging.handle(), dst.handle(), 1, &region);
  });
  return dst;
}

std::vector<std::byte> read_buffer(Context& ctx, const Buffer& buffer) {
  std::vector<std::byte> out(buffer.size());
  if (out.empty()) return out;
  if (buffer.mapped()) {
    std::memcpy(out.data(), buffer.mapped(), out.size());
    return out;
  }
  Buffer staging(ctx, buffer.size(), VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  ctx.submit_and_wait([&](VkCommandBuffer cmd) {
    VkBufferCopy region{0, 0, buffer.size()};
    vkCmdCopyBuffer(cmd, buffer.handle(), staging.handle(), 1, &region);
  });
  std::memcpy(out.data(), staging.mapped(), out.size());
  return out;
}

std::vector<std::byte> read_image(Context& ctx, const Image& image, VkImageLayout layout) {
  const VkDeviceSize size = VkDeviceSize(image.width()) * image.height() * format_size_bytes(image.format());
  Buffer staging(ctx, size, VK_BUFFER_USAGE_TRANSFER_DST_BIT, true);
  ctx.submit_and_wait([&](VkCommandBuffer cmd) {
    transition(cmd, image, layout, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT,
               VK_ACCESS_2_MEMORY_WRITE_BIT, VK_PIPELINE_STAGE_2_COPY_BIT, VK_ACCESS_2_TRANSFER_READ_BIT);
    VkBufferImageCopy region{};
    region.imageSubresource = {image.aspect(), 0, 0, 1};
    region.imageExtent = {image.width(), image.height(), 1};
    vkCmdCopyImageToBuffer(cmd, image.handle(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, staging.handle(), 1, &region);
    transition(cmd, image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, layout, VK_PIPELINE_STAGE_2_COPY_BIT,
               VK_ACCESS_2_TRANSFER_READ_BIT, VK_PIPELINE_STAGE_2_ALL_COMMANDS_BIT,
               VK_ACCESS_2_MEMORY_READ_BIT | VK_ACCESS_2_MEMORY_WRITE_BIT);
  });
  std::vector<std::byte> out(size);
  std::memcpy(out.data(), staging.mapped(), size);
  return out;
}

void transition(VkCommandBuffer cmd, const Image& image, VkImageLayout from, VkImageLayout to,
                VkPipelineStageFlags2 src_stage, VkAccessFlags2 src_access, VkPipelineStageFlags2 dst_stage,
                VkAccessFlags2 dst_access) {
  VkImageMemoryBarrier2 b{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER_2};
  b.srcStageMask = src_stage;
  b.srcAccessMask = src_access;
  b.dstStageMask = dst_stage;
  b.dstAccessMask = dst_access;
  b.oldLayout = from;
  b.newLayout = to;
  b.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  b.image = image.handle();
  b.subresourceRange = {image.aspect(), 0, 1, 0, 1};
  VkDependencyInfo dep{VK_STRUCTURE_TYPE_DEPENDENCY_INFO};
  dep.imageMemoryBarrierCount = 1;
  dep.pImageMemoryBarriers = &b;
  vkCmdPipelineBarrier2(cmd, &dep);
}

void memory_barrier(VkCommandBuffer cmd, VkPipelineStageFlags2 src_stage, VkAccessFlags2 src_access,
                    VkPipelineStageFlags2 dst_stage, VkAccessFlags2 dst_access) {
  VkMemoryBarrier2 b{VK_STRUCTURE_TYPE_MEMORY_BARRIER_2};
  b.srcStageMask = src_stage;
  b.srcAccessMask = src_access;
  b.dstStageMask = dst_stage;
  b.dstAccessMask = dst_access;
  VkDependencyInfo dep{VK_STRUCTURE_TYPE_DEPENDENCY_INFO};
  dep.memoryBarrierCount = 1;
  dep.pMemoryBarriers = &b;
  vkCmdPipelineBarrier2(cmd, &dep);
}

}  // namespace hp::vk
