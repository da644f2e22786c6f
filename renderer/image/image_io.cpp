#include "atomic_file.hpp"
#include "error.hpp"
#include "image/image.hpp"
#include "output_path.hpp"

#include "image/image_backend.hpp"

#include <dlfcn.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <mutex>

namespace hp {

float linear_to_srgb(float x) {
  x = std::clamp(x, 0.0f, 1.0f);
  return x <= 0.0031308f ? 12.92f * x : 1.055f * std::pow(x, 1.0f / 2.4f) - 0.055f;
}

float srgb_to_linear(float x) { return x <= 0.04045f ? x / 12.92f : std::pow((x + 0.055f) / 1.055f, 2.4f); }

namespace {
std::string lower_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext;
}
}  // namespace

void check_image_output(const std::string& path, const std::string& what, bool parent_must_exist) {
  const std::string ext = lower_extension(path);
  if (ext != ".png" && ext != ".exr") {
    throw InputError((what.empty() ? "" : what + " ") + path + ": unsupported image extension '" + ext +
                     "' (use .png or .exr)");
  }
  check_output_path(path, what, parent_must_exist);
}

namespace {
// OpenImageIO is loaded with the first image read or written (see oiio_backend.cpp for why). The module's
// path is the one the build wrote (HP_IMAGE_MODULE, absolute); HP_IMAGE_MODULE in the environment overrides it.
const ImageBackend& backend() {
  static const ImageBackend* loaded = nullptr;
  static std::string failure;
  static std::once_flag once;
  std::call_once(once, [] {
    const char* env = std::getenv("HP_IMAGE_MODULE");
    const std::string path = env && *env ? env : HP_IMAGE_MODULE;
    void* lib = ::dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
      const char* e = ::dlerror();
      failure = "cannot load the image module " + path + ": " + (e ? e : "unknown error");
      return;
    }
    using Entry = const ImageBackend* (*)();
    auto entry = reinterpret_cast<Entry>(::dlsym(lib, "hp_image_backend"));
    const ImageBackend* b = entry ? entry() : nullptr;
    if (!b || b->version != kImageBackendVersion) {
      failure = "the image module " + path + " is not this build's (rebuild hybridprof)";
      return;
    }
    loaded = b;
  });
  if (!loaded) throw InputError(failure);
  return *loaded;
}
}  // namespace

void write_image(const std::string& path, const Image4f& image) {
  check_image_output(path, "", /*parent_must_exist=*/false);  // it makes its folders (the commands check first)
  const bool exr = lower_extension(path) == ".exr";
  const ImageBackend& io = backend();
  // The temporary keeps the extension, so OpenImageIO picks the right format.
  AtomicFile file(path, "", /*create_folders=*/true);
  std::string error;
  bool ok = false;
  if (exr) {
    ok = io.write(file.temp_path().string(), true, image.width, image.height, image.rgba.data(), error);
  } else {
    std::vector<uint8_t> px(image.rgba.size());
    for (size_t i = 0; i < image.rgba.size(); ++i) {
      const float v = (i % 4 == 3) ? std::clamp(image.rgba[i], 0.0f, 1.0f) : linear_to_srgb(image.rgba[i]);
      px[i] = static_cast<uint8_t>(std::lround(v * 255.0f));
    }
    ok = io.write(file.temp_path().string(), false, image.width, image.height, px.data(), error);
  }
  if (!ok) throw InputError(path + ": " + error);
  file.commit();
}

Image4f read_image(const std::string& path) {
  DecodedImage d;
  std::string error;
  if (!backend().read(path, d, error)) throw InputError(path + ": " + error);
  Image4f img(d.width, d.height);
  const int nc = d.channels;
  for (size_t i = 0; i < size_t(d.width) * d.height; ++i) {
    for (int c = 0; c < 4; ++c) {
      float v = c < nc ? d.pixels[i * nc + c] : (c == 3 ? 1.0f : 0.0f);
      if (c < 3 && nc < 3) v = d.pixels[i * nc];  // grey
      if (d.srgb && c < 3) v = srgb_to_linear(v);
      img.rgba[i * 4 + c] = v;
    }
  }
  return img;
}

}  // namespace hp
