// The headless Vulkan context: instance (optionally with the validation layer and a debug messenger),
// the chosen physical device, one queue that does graphics + compute + transfer, a command pool.
// No window, no surface. Move-only; destroys everything it created.
#pragma once

#include <vulkan/vulkan.h>

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace hp::vk {

struct ContextOptions {
  /// "" = default choice (a discrete GPU if present, else lavapipe, else the first device);
  /// a decimal index into the enumeration order; or a case-insensitive substring of the device name.
  std::string device;
  /// Enable VK_LAYER_KHRONOS_validation with a debug messenger that counts (and prints) every message.
  bool validate = false;
  /// Print validation messages to stderr as they arrive.
  bool print_messages = true;
};

/// What a result file records about the device (environment capture).
struct DeviceInfo {
  std::string name;
  std::string type;  ///< "discrete", "integrated", "cpu", "virtual", "other"
  std::string driver_name;
  std::string driver_info;
  /// The driver's version: for Mesa's drivers the release their driverInfo names ("25.0.7-2~bpo12+1"; their
  /// driverVersion field is a constant, 0.0.1 for lavapipe), else driverVersion decoded, NVIDIA's
  /// 10.8.8.6-bit layout ("580.95.5.0") or VK_MAKE_API_VERSION's for every other vendor.
  std::string driver_version;
  std::string api_version;
  uint32_t vendor_id = 0;
  uint32_t device_id = 0;
  uint32_t subgroup_size = 0;
  /// Subgroup ballot (and the basic operations) in compute shaders: the instrumented variants of a memory
  /// trace reserve their record slots with it.
  bool subgroup_ballot_compute = false;
  double timestamp_period_ns = 0.0;
  uint32_t timestamp_valid_bits = 0;
  uint64_t max_storage_buffer_range = 0;
  /// The driver's ray tracing, usable as hybridprof uses it: acceleration structures (built on the device),
  /// buffer device addresses, and ray queries in compute shaders / ray-tracing pipelines.
  bool ray_query = false;
  bool ray_tracing_pipeline = false;
};

/// DeviceInfo::driver_version from driverInfo, vendorID and driverVersion.
std::string driver_version_string(const std::string& driver_info, uint32_t vendor_id, uint32_t driver_version);

/// The entry points of VK_KHR_acceleration_structure and VK_KHR_ray_tracing_pipeline (loaded from the device;
/// null where the extension is not enabled).
struct RayTracingFunctions {
  PFN_vkGetAccelerationStructureBuildSizesKHR get_build_sizes = nullptr;
  PFN_vkCreateAccelerationStructureKHR create_as = nullptr;
  PFN_vkDestroyAccelerationStructureKHR destroy_as = nullptr;
  PFN_vkCmdBuildAccelerationStructuresKHR cmd_build = nullptr;
  PFN_vkCmdCopyAccelerationStructureKHR cmd_copy = nullptr;
  PFN_vkCmdWriteAccelerationStructuresPropertiesKHR cmd_write_properties = nullptr;
  PFN_vkGetAccelerationStructureDeviceAddressKHR get_as_address = nullptr;
  PFN_vkCreateRayTracingPipelinesKHR create_pipelines = nullptr;
  PFN_vkGetRayTracingShaderGroupHandlesKHR get_group_handles = nullptr;
  PFN_vkCmdTraceRaysKHR cmd_trace_rays = nullptr;
  PFN_vkCmdTraceRaysIndirectKHR cmd_trace_rays_indirect = nullptr;
};

/// All physical devices the loader sees, in enumeration order (for `--device` and `hybridprof devices`).
std::vector<DeviceInfo> list_devices();

class Context {
 public:
  /// Throws hp::DeviceError when there is no Vulkan device (or none that matches options.device, or the
  /// chosen one lacks Vulkan 1.3 dynamic rendering / synchronization2).
  explicit Context(const ContextOptions& options = {});
  ~Context();
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  VkInstance instance() const { return instance_; }
  VkPhysicalDevice physical_device() const { return physical_; }
  VkDevice device() const { return device_; }
  VkQueue queue() const { return queue_; }
  uint32_t queue_family() const { return queue_family_; }
  VkCommandPool command_pool() const { return pool_; }
  const DeviceInfo& info() const { return info_; }
  const VkPhysicalDeviceProperties& properties() const { return props_; }
  const VkPhysicalDeviceMemoryProperties& memory_properties() const { return mem_props_; }
  /// Ray queries / ray-tracing pipelines are enabled on this device (DeviceInfo says which it has; both
  /// bring acceleration structures and buffer device addresses).
  bool ray_query_enabled() const { return info_.ray_query; }
  bool ray_tracing_pipeline_enabled() const { return info_.ray_tracing_pipeline; }
  bool buffer_device_address_enabled() const { return info_.ray_query || info_.ray_tracing_pipeline; }
  const RayTracingFunctions& rt() const { return rt_; }
  /// VK_KHR_ray_tracing_pipeline's shader group handle size and alignments (zero without it).
  const VkPhysicalDeviceRayTracingPipelinePropertiesKHR& rt_pipeline_properties() const { return rt_props_; }
  bool validation_enabled() const { return messenger_ != VK_NULL_HANDLE; }
  /// Validation messages (warnings and errors) received so far.
  uint64_t validation_message_count() const { return messages_->count.load(); }
  std::string last_validation_message() const;

  /// A memory type index with all `required` flags among `type_bits`; throws DeviceError if none.
  uint32_t find_memory_type(uint32_t type_bits, VkMemoryPropertyFlags required) const;

  /// Records commands with `record`, submits them, waits for completion (one-shot).
  template <typename F>
  void submit_and_wait(F&& record) {
    VkCommandBuffer cmd = begin_one_shot();
    record(cmd);
    end_one_shot(cmd);
  }
  VkCommandBuffer begin_one_shot();
  void end_one_shot(VkCommandBuffer cmd);

  struct MessageLog {
    std::atomic<uint64_t> count{0};
    bool print = true;
    std::string last;
  };

 private:
  void release();

  VkInstance instance_ = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
  VkPhysicalDevice physical_ = VK_NULL_HANDLE;
  VkDevice device_ = VK_NULL_HANDLE;
  VkQueue queue_ = VK_NULL_HANDLE;
  uint32_t queue_family_ = 0;
  VkCommandPool pool_ = VK_NULL_HANDLE;
  VkFence fence_ = VK_NULL_HANDLE;
  VkPhysicalDeviceProperties props_{};
  VkPhysicalDeviceMemoryProperties mem_props_{};
  DeviceInfo info_;
  RayTracingFunctions rt_;
  VkPhysicalDeviceRayTracingPipelinePropertiesKHR rt_props_{};
  std::unique_ptr<MessageLog> messages_ = std::make_unique<MessageLog>();
};

/// Whether the Khronos validation layer is installed (tests enable it when it is).
bool validation_layer_available();

}  // namespace hp::vk
