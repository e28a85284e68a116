// PNG encode/decode through libpng's simplified API (png_image_*), which handles the format's
// details (filters, zlib, chunk CRCs); we add the atomic write and error messages that name the file.
#include <png.h>

#include <cstring>
#include <string>

#include "duplexfit/atomic_file.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/image.hpp"

namespace duplexfit {

namespace {

png_uint_32 formatFor(int channels) {
  switch (channels) {
    case 1: return PNG_FORMAT_GRAY;
    case 3: return PNG_FORMAT_RGB;
    case 4: return PNG_FORMAT_RGBA;
    default: throw InvalidArgument("image: " + std::to_string(channels) + " channels (expected 1, 3 or 4)");
  }
}

}  // namespace

Image::Image(int w, int h, int c, std::uint8_t fill) : width(w), height(h), channels(c) {
  if (w < 1 || h < 1 || w > 65536 || h > 65536) {
    throw InvalidArgument("image: size " + std::to_string(w) + "x" + std::to_string(h) +
                          " (each side must be 1..65536)");
  }
  formatFor(c);
  pixels.assign(static_cast<std::size_t>(w) * h * c, fill);
}

void writePng(const std::string& path, const Image& image) {
  const png_uint_32 format = formatFor(image.channels);
  if (image.width < 1 || image.height < 1 ||
      image.pixels.size() != static_cast<std::size_t>(image.width) * image.height * image.channels) {
    throw InvalidArgument("writePng(" + path + "): pixel buffer does not match " + std::to_string(image.width) +
                          "x" + std::to_string(image.height) + "x" + std::to_string(image.channels));
  }
  png_image png;
  std::memset(&png, 0, sizeof png);
  png.version = PNG_IMAGE_VERSION;
  png.width = static_cast<png_uint_32>(image.width);
  png.height = static_cast<png_uint_32>(image.height);
  png.format = format;
  png_alloc_size_t bytes = 0;
  // First call sizes the in-memory PNG, the second encodes it.
  if (!png_image_write_to_memory(&png, nullptr, &bytes, 0, image.pixels.data(), 0, nullptr)) {
    const std::string message = png.message;
    png_image_free(&png);
    throw IoError("writePng(" + path + "): " + message);
  }
  std::vector<unsigned char> buffer(bytes);
  if (!png_image_write_to_memory(&png, buffer.data(), &bytes, 0, image.pixels.data(), 0, nullptr)) {
    const std::string message = png.message;
    png_image_free(&png);
    throw IoError("writePng(" + path + "): " + message);
  }
  png_image_free(&png);
  AtomicFile out(path);
  out.write(buffer.data(), bytes);
  out.commit();
}

Image readPng(const std::string& path) {
  png_image png;
  std::memset(&png, 0, sizeof png);
  png.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&png, path.c_str())) {
    const std::string message = png.message;
    png_image_free(&png);
    throw IoError("readPng(" + path + "): " + message);
  }
  int channels = 3;
  if ((png.format & PNG_FORMAT_FLAG_COLOR) == 0 && (png.format & PNG_FORMAT_FLAG_ALPHA) == 0) {
    channels = 1;
    png.format = PNG_FORMAT_GRAY;
  } else if (png.format & PNG_FORMAT_FLAG_ALPHA) {
    channels = 4;
    png.format = PNG_FORMAT_RGBA;
  } else {
    png.format = PNG_FORMAT_RGB;
  }
  Image image;
  image.width = static_cast<int>(png.width);
  image.height = static_cast<int>(png.height);
  image.channels = channels;
  image.pixels.resize(PNG_IMAGE_SIZE(png));
  if (!png_image_finish_read(&png, nullptr, image.pixels.data(), 0, nullptr)) {
    const std::string message = png.message;
    png_image_free(&png);
    throw IoError("readPng(" + path + "): " + message);
  }
  return image;
}

}  // namespace duplexfit
