#pragma once
// The interface between image_io.cpp and the OpenImageIO module it loads on first use (oiio_backend.cpp).
// Both are built together by this project, so C++ types cross it; the version catches a stale module.
#include <cstdint>
#include <string>
#include <vector>

namespace hp {

inline constexpr uint32_t kImageBackendVersion = 1;

struct DecodedImage {
  uint32_t width = 0, height = 0;
  int channels = 0;
  bool srgb = false;          ///< 8- or 16-bit integer samples (PNG): sRGB-encoded
  std::vector<float> pixels;  ///< channels floats per pixel, in [0, 1] for integer formats
};

struct ImageBackend {
  uint32_t version;
  bool (*write)(const std::string& tmp, bool exr, uint32_t width, uint32_t height, const void* rgba,
                std::string& error);
  bool (*read)(const std::string& path, DecodedImage& image, std::string& error);
};

}  // namespace hp

/// The module's one exported symbol.
extern "C" const hp::ImageBackend* hp_image_backend();
