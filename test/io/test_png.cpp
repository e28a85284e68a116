// PNG round trips through libpng for grey, RGB and RGBA images; bad images and bad files give clear
// errors and leave no file behind.
#include <doctest/doctest.h>

#include <filesystem>
#include <string>

#include "duplexfit/error.hpp"
#include "duplexfit/image.hpp"
#include "io_test_util.hpp"

using duplexfit::Image;
using duplexfit::testing::TempDir;

TEST_SUITE("io") {

TEST_CASE("png: grey, RGB and RGBA images round-trip sample for sample") {
  TempDir dir;
  for (int channels : {1, 3, 4}) {
    CAPTURE(channels);
    Image image(37, 11, channels);
    for (std::size_t i = 0; i < image.pixels.size(); ++i) image.pixels[i] = static_cast<std::uint8_t>((i * 7919u) % 251u);
    const std::string path = dir.file("img" + std::to_string(channels) + ".png");
    duplexfit::writePng(path, image);
    const Image back = duplexfit::readPng(path);
    CHECK(back.width == 37);
    CHECK(back.height == 11);
    CHECK(back.channels == channels);
    CHECK(back.pixels == image.pixels);
  }
  // at() addresses row y, column x.
  Image rgb(4, 3, 3, 0);
  rgb.at(2, 1)[0] = 200;
  CHECK(rgb.pixels[(1 * 4 + 2) * 3] == 200);
}

TEST_CASE("png: a resolution goes into a pHYs chunk (pixels per metre, unit byte 1); none without one") {
  TempDir dir;
  Image image(5, 3, 1, 7);
  duplexfit::writePng(dir.file("dpi.png"), image, 11811);  // 300 DPI
  duplexfit::writePng(dir.file("plain.png"), image);
  const std::string with = duplexfit::testing::readFile(dir.file("dpi.png"));
  const std::string without = duplexfit::testing::readFile(dir.file("plain.png"));
  const auto at = with.find("pHYs");
  REQUIRE(at != std::string::npos);
  REQUIRE(at >= 4);
  auto byte = [&](std::size_t i) { return static_cast<unsigned>(static_cast<unsigned char>(with[i])); };
  CHECK(((byte(at - 4) << 24) | (byte(at - 3) << 16) | (byte(at - 2) << 8) | byte(at - 1)) == 9u);  // length
  const std::size_t d = at + 4;
  CHECK(((byte(d) << 24) | (byte(d + 1) << 16) | (byte(d + 2) << 8) | byte(d + 3)) == 11811u);
  CHECK(((byte(d + 4) << 24) | (byte(d + 5) << 16) | (byte(d + 6) << 8) | byte(d + 7)) == 11811u);
  CHECK(byte(d + 8) == 1u);
  CHECK(without.find("pHYs") == std::string::npos);
  CHECK(duplexfit::readPng(dir.file("dpi.png")).pixels == image.pixels);
  CHECK_THROWS_AS(duplexfit::writePng(dir.file("big.png"), image, 0x80000000u), duplexfit::InvalidArgument);
  CHECK_FALSE(std::filesystem::exists(dir.file("big.png")));
}

TEST_CASE("png: bad sizes, bad buffers and unreadable files are clear errors; nothing half-written") {
  TempDir dir;
  CHECK_THROWS_AS(Image(0, 5, 3), duplexfit::InvalidArgument);
  CHECK_THROWS_AS(Image(5, 5, 2), duplexfit::InvalidArgument);
  Image broken(4, 4, 3);
  broken.pixels.resize(10);
  CHECK_THROWS_AS(duplexfit::writePng(dir.file("broken.png"), broken), duplexfit::InvalidArgument);
  CHECK(dir.entries().empty());
  CHECK_THROWS_AS(duplexfit::writePng(dir.file("missing/folder.png"), Image(2, 2, 1)), duplexfit::IoError);
  duplexfit::testing::writeBytes(dir.file("not.png"), std::string("not png"));
  try {
    duplexfit::readPng(dir.file("not.png"));
    FAIL("expected IoError");
  } catch (const duplexfit::IoError& e) {
    CHECK(std::string(e.what()).find("not.png") != std::string::npos);
  }
  CHECK_THROWS_AS(duplexfit::readPng(dir.file("absent.png")), duplexfit::IoError);
}

}  // TEST_SUITE
