// PNG encode/decode through libpng: writing with the regular API (for the pHYs chunk), reading with the
// simplified API (png_image_*); libpng handles filters, zlib and chunk CRCs. We add the atomic write and
// error messages that name the file.
#include <png.h>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <utility>
#include <vector>

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

namespace {

// The regular write API (png_create_write_struct …) instead of png_image_write_*, which cannot write a
// pHYs chunk. libpng reports errors through pngError, which longjmps back to encodePng's setjmp: between
// setjmp and the end of encodePng no C++ object with a destructor lives in that frame, nothing modified
// after setjmp is read after the jump, and no exception crosses libpng's C frames.
struct WriteContext {
  const Image* image = nullptr;
  png_bytep* rows = nullptr;         // one pointer per row of *image
  std::uint32_t pixelsPerMetre = 0;  // > 0: a pHYs chunk
  png_structp png = nullptr;
  png_infop info = nullptr;
  std::vector<unsigned char> bytes;  // the encoded file
  char message[256] = {0};
};

void pngError(png_structp png, png_const_charp message) {
  auto* ctx = static_cast<WriteContext*>(png_get_error_ptr(png));
  std::snprintf(ctx->message, sizeof ctx->message, "%s", message != nullptr ? message : "libpng error");
  png_longjmp(png, 1);
}

void pngWarning(png_structp, png_const_charp) {}

void pngWriteData(png_structp png, png_bytep data, png_size_t length) {
  auto* ctx = static_cast<WriteContext*>(png_get_io_ptr(png));
  bool failed = false;
  try {
    ctx->bytes.insert(ctx->bytes.end(), data, data + length);
  } catch (...) {
    failed = true;
  }
  if (failed) png_error(png, "out of memory while encoding");  // outside the catch block: it longjmps
}

void pngFlush(png_structp) {}

int colorTypeFor(int channels) {
  return channels == 1 ? PNG_COLOR_TYPE_GRAY : channels == 3 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_RGBA;
}

/// Encodes ctx.image into ctx.bytes; false with ctx.message on a libpng error. Everything the jump back
/// needs lives in *ctx (memory, not locals that setjmp could clobber).
bool encodeInto(WriteContext* ctx) {
  ctx->png = png_create_write_struct(PNG_LIBPNG_VER_STRING, ctx, pngError, pngWarning);
  if (ctx->png == nullptr) {
    std::snprintf(ctx->message, sizeof ctx->message, "cannot create the PNG writer");
    return false;
  }
  ctx->info = png_create_info_struct(ctx->png);
  if (ctx->info == nullptr) {
    png_destroy_write_struct(&ctx->png, nullptr);
    std::snprintf(ctx->message, sizeof ctx->message, "cannot create the PNG info");
    return false;
  }
  if (setjmp(png_jmpbuf(ctx->png))) {
    png_destroy_write_struct(&ctx->png, &ctx->info);
    return false;
  }
  const Image& image = *ctx->image;
  png_set_write_fn(ctx->png, ctx, pngWriteData, pngFlush);
  png_set_IHDR(ctx->png, ctx->info, static_cast<png_uint_32>(image.width), static_cast<png_uint_32>(image.height), 8,
               colorTypeFor(image.channels), PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  if (ctx->pixelsPerMetre > 0) {
    png_set_pHYs(ctx->png, ctx->info, ctx->pixelsPerMetre, ctx->pixelsPerMetre, PNG_RESOLUTION_METER);
  }
  png_set_rows(ctx->png, ctx->info, ctx->rows);
  png_write_png(ctx->png, ctx->info, PNG_TRANSFORM_IDENTITY, nullptr);
  png_destroy_write_struct(&ctx->png, &ctx->info);
  return true;
}

}  // namespace

namespace {

/// The PNG file of `image`; `what` names the output in error messages.
std::vector<unsigned char> encodeChecked(const Image& image, std::uint32_t pixelsPerMetre, const std::string& what) {
  formatFor(image.channels);
  if (image.width < 1 || image.height < 1 ||
      image.pixels.size() != static_cast<std::size_t>(image.width) * image.height * image.channels) {
    throw InvalidArgument(what + ": pixel buffer does not match " + std::to_string(image.width) + "x" +
                          std::to_string(image.height) + "x" + std::to_string(image.channels));
  }
  if (pixelsPerMetre > 0x7fffffffu) {
    throw InvalidArgument(what + ": " + std::to_string(pixelsPerMetre) +
                          " pixels per metre exceeds the PNG limit 2^31 - 1");
  }
  // libpng takes non-const row pointers; with PNG_TRANSFORM_IDENTITY it only reads them.
  std::vector<png_bytep> rows(static_cast<std::size_t>(image.height));
  const std::size_t stride = static_cast<std::size_t>(image.width) * image.channels;
  for (std::size_t y = 0; y < rows.size(); ++y) rows[y] = const_cast<png_bytep>(image.pixels.data() + y * stride);
  WriteContext ctx;
  ctx.image = &image;
  ctx.rows = rows.data();
  ctx.pixelsPerMetre = pixelsPerMetre;
  if (!encodeInto(&ctx)) throw IoError(what + ": " + ctx.message);
  return std::move(ctx.bytes);
}

}  // namespace

std::vector<std::uint8_t> encodePng(const Image& image, std::uint32_t pixelsPerMetre) {
  return encodeChecked(image, pixelsPerMetre, "encodePng");
}

void writePng(const std::string& path, const Image& image, std::uint32_t pixelsPerMetre) {
  const std::vector<unsigned char> bytes = encodeChecked(image, pixelsPerMetre, "writePng(" + path + ")");
  AtomicFile out(path);
  out.write(bytes.data(), bytes.size());
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
