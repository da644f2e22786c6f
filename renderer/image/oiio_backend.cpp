// The OpenImageIO side of image_io.cpp, built as a module that image_io.cpp loads (dlopen) on the first
// image read or write. OpenImageIO and the libraries it links take about 0.24 s and 130 MB to load on the
// 2-core VM; a command that reads no image (cachesim, gate, report, bvh, run without images) does not pay it.
#include "image/image_backend.hpp"

#include <OpenImageIO/imageio.h>

#include <vector>

namespace hp {
namespace {

namespace OIIO = OIIO_NAMESPACE;

// `rgba` is 4 floats per pixel (EXR) or, for PNG, 4 bytes per pixel already encoded.
bool write(const std::string& tmp, bool exr, uint32_t width, uint32_t height, const void* rgba, std::string& error) {
  auto out = OIIO::ImageOutput::create(tmp);
  if (!out) {
    error = "cannot create an image writer: " + OIIO::geterror();
    return false;
  }
  const OIIO::TypeDesc type = exr ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8;
  OIIO::ImageSpec spec(int(width), int(height), 4, type);
  if (exr) spec.attribute("compression", "zip");
  bool ok = out->open(tmp, spec) && out->write_image(type, rgba);
  std::string err = out->geterror();
  ok = out->close() && ok;
  if (!ok) error = "cannot write image: " + (err.empty() ? std::string("unknown error") : err);
  return ok;
}

bool read(const std::string& path, DecodedImage& image, std::string& error) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) {
    error = "cannot read image: " + OIIO::geterror();
    return false;
  }
  const OIIO::ImageSpec& spec = in->spec();
  image.width = uint32_t(spec.width);
  image.height = uint32_t(spec.height);
  image.channels = spec.nchannels;
  image.srgb = spec.format == OIIO::TypeDesc::UINT8 || spec.format == OIIO::TypeDesc::UINT16;
  image.pixels.resize(size_t(spec.width) * spec.height * spec.nchannels);
  if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, image.pixels.data())) {
    error = "cannot read image: " + in->geterror();
    return false;
  }
  in->close();
  return true;
}

const ImageBackend kBackend{kImageBackendVersion, &write, &read};

}  // namespace
}  // namespace hp

extern "C" const hp::ImageBackend* hp_image_backend() { return &hp::kBackend; }
