#include "atomic_file.hpp"
#include "error.hpp"
#include "image/image.hpp"
#include "output_path.hpp"

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>

namespace hp {

namespace OIIO = OIIO_NAMESPACE;

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

void write_image(const std::string& path, const Image4f& image) {
  check_image_output(path, "", /*parent_must_exist=*/false);  // it makes its folders (the commands check first)
  const std::string ext = lower_extension(path);
  // The temporary keeps the extension, so OpenImageIO picks the right format.
  AtomicFile file(path, "", /*create_folders=*/true);
  const std::string tmp = file.temp_path().string();
  auto out = OIIO::ImageOutput::create(tmp);
  if (!out) throw InputError(path + ": cannot create an image writer: " + OIIO::geterror());
  bool ok = false;
  if (ext == ".exr") {
    OIIO::ImageSpec spec(int(image.width), int(image.height), 4, OIIO::TypeDesc::FLOAT);
    spec.attribute("compression", "zip");
    ok = out->open(tmp, spec) && out->write_image(OIIO::TypeDesc::FLOAT, image.rgba.data());
  } else {
    OIIO::ImageSpec spec(int(image.width), int(image.height), 4, OIIO::TypeDesc::UINT8);
    std::vector<uint8_t> px(image.rgba.size());
    for (size_t i = 0; i < image.rgba.size(); ++i) {
      const float v = (i % 4 == 3) ? std::clamp(image.rgba[i], 0.0f, 1.0f) : linear_to_srgb(image.rgba[i]);
      px[i] = static_cast<uint8_t>(std::lround(v * 255.0f));
    }
    ok = out->open(tmp, spec) && out->write_image(OIIO::TypeDesc::UINT8, px.data());
  }
  std::string err = out->geterror();
  ok = out->close() && ok;
  if (!ok) throw InputError(path + ": cannot write image: " + (err.empty() ? std::string("unknown error") : err));
  file.commit();
}

Image4f read_image(const std::string& path) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) throw InputError(path + ": cannot read image: " + OIIO::geterror());
  const OIIO::ImageSpec& spec = in->spec();
  Image4f img(uint32_t(spec.width), uint32_t(spec.height));
  std::vector<float> px(size_t(spec.width) * spec.height * spec.nchannels);
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, px.data())) {
    throw InputError(path + ": cannot read image: " + in->geterror());
  }
  const bool srgb = spec.format == OIIO::TypeDesc::UINT8 || spec.format == OIIO::TypeDesc::UINT16;
  for (size_t i = 0; i < size_t(spec.width) * spec.height; ++i) {
    for (int c = 0; c < 4; ++c) {
      float v = c < spec.nchannels ? px[i * spec.nchannels + c] : (c == 3 ? 1.0f : 0.0f);
      if (c < 3 && spec.nchannels < 3) v = px[i * spec.nchannels];  // grey
      if (srgb && c < 3) v = srgb_to_linear(v);
      img.rgba[i * 4 + c] = v;
    }
  }
  in->close();
  return img;
}

}  // namespace hp
