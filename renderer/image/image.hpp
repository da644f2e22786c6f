// A host-side float image (RGBA, linear) and the conversions the CLI and tests need. No Vulkan, no files.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace hp {

struct Image4f {
  uint32_t width = 0;
  uint32_t height = 0;
  std::vector<float> rgba;  ///< width * height * 4, row-major, top row first

  Image4f() = default;
  Image4f(uint32_t w, uint32_t h) : width(w), height(h), rgba(std::size_t(w) * h * 4, 0.0f) {}
  float* at(uint32_t x, uint32_t y) { return &rgba[(std::size_t(y) * width + x) * 4]; }
  const float* at(uint32_t x, uint32_t y) const { return &rgba[(std::size_t(y) * width + x) * 4]; }
};

/// Writes an image; the format follows the extension: `.exr` keeps linear floats (32-bit), `.png` applies
/// the display transform (clamp, sRGB encoding). Written to a temporary file and renamed, so a failed
/// write leaves nothing behind. Throws hp::InputError naming the path on failure.
void write_image(const std::string& path, const Image4f& image);

/// What write_image checks before writing (a .png or .exr extension, a path that can be written:
/// check_output_path), for commands to call before the work that produces the image. `what` prefixes the
/// error (an option name such as "--image").
void check_image_output(const std::string& path, const std::string& what, bool parent_must_exist = true);

/// Reads an image as linear floats (PNG is decoded from sRGB). Throws hp::InputError naming the path.
Image4f read_image(const std::string& path);

/// Linear -> sRGB transfer function for one channel in [0, 1].
float linear_to_srgb(float x);
float srgb_to_linear(float x);

}  // namespace hp
