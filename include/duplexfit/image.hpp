// 8-bit raster images and PNG files (through libpng): the section pictures and the slice masks.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace duplexfit {

/// An 8-bit image, rows top to bottom, `channels` interleaved samples per pixel (1 grey, 3 RGB,
/// 4 RGBA).
struct Image {
  int width = 0;
  int height = 0;
  int channels = 3;
  std::vector<std::uint8_t> pixels;  ///< width * height * channels samples

  Image() = default;
  /// A width x height image filled with `fill` in every sample.
  /// @throws InvalidArgument for a size < 1, a size over 65536 or channels not 1, 3 or 4.
  Image(int width, int height, int channels, std::uint8_t fill = 0);

  std::uint8_t* at(int x, int y) { return pixels.data() + (static_cast<std::size_t>(y) * width + x) * channels; }
  const std::uint8_t* at(int x, int y) const {
    return pixels.data() + (static_cast<std::size_t>(y) * width + x) * channels;
  }
};

/// Writes `image` as an 8-bit PNG (grey, RGB or RGBA), atomically (temporary file + rename). With
/// `pixelsPerMetre` > 0 the file gets a pHYs chunk with that resolution on both axes (unit: metre; DPI =
/// pixelsPerMetre · 0.0254). @throws InvalidArgument for an inconsistent image or pixelsPerMetre > 2^31 − 1,
/// IoError naming `path` on a write error.
void writePng(const std::string& path, const Image& image, std::uint32_t pixelsPerMetre = 0);
/// The bytes of the PNG file writePng would write (for outputs packed into an archive).
/// @throws InvalidArgument as writePng, IoError on an encoder error.
std::vector<std::uint8_t> encodePng(const Image& image, std::uint32_t pixelsPerMetre = 0);

/// Reads an 8-bit or 16-bit grey/RGB/RGBA or palette PNG into 8-bit samples (16-bit scaled down,
/// palette expanded to RGB). @throws IoError naming `path` when it is missing or not a valid PNG.
Image readPng(const std::string& path);

}  // namespace duplexfit
