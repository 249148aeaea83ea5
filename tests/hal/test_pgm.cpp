#include <gtest/gtest.h>

#include <fstream>
#include <stdexcept>

#include "sempose/hal/pgm.hpp"
#include "test_util.hpp"

namespace sempose::hal {
namespace {

void write_raw(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

std::string error_of(const std::string& path) {
  Image img;
  img.width = 7;  // must stay untouched on failure
  std::string error;
  EXPECT_FALSE(try_read_pgm(path, img, error));
  EXPECT_EQ(img.width, 7) << "half-read image";
  EXPECT_NE(error.find(path), std::string::npos) << error;
  EXPECT_THROW(read_pgm(path), std::runtime_error);
  return error;
}

TEST(Pgm, RoundTrip8And16Bit) {
  const auto dir = test::temp_dir("pgm");
  for (int bits : {8, 16}) {
    Image img;
    img.width = 37;
    img.height = 11;
    img.bits = static_cast<std::uint8_t>(bits);
    for (int i = 0; i < img.width * img.height; ++i) {
      img.pixels.push_back(static_cast<std::uint16_t>(bits == 8 ? (i * 7) % 256 : (i * 977) % 65536));
    }
    const std::string path = (dir / ("rt" + std::to_string(bits) + ".pgm")).string();
    write_pgm(path, img);
    const Image back = read_pgm(path);
    EXPECT_EQ(back.width, img.width);
    EXPECT_EQ(back.height, img.height);
    EXPECT_EQ(back.bits, bits);
    EXPECT_EQ(back.pixels, img.pixels);
  }
}

TEST(Pgm, SixteenBitIsBigEndian) {
  const auto dir = test::temp_dir("pgm_be");
  const std::string path = (dir / "be.pgm").string();
  write_raw(path, std::string("P5\n2 1\n65535\n\x01\x02\xff\x00", 17));  // no trailing NUL
  const Image img = read_pgm(path);
  EXPECT_EQ(img.bits, 16);
  EXPECT_EQ(img.pixels[0], 0x0102);
  EXPECT_EQ(img.pixels[1], 0xff00);
}

TEST(Pgm, CommentsAllowedInHeader) {
  const auto dir = test::temp_dir("pgm_comment");
  const std::string path = (dir / "c.pgm").string();
  write_raw(path, "P5 # made by hand\n# a full comment line\n3 # width\n2\n# maxval next\n255\nabcdef");
  const Image img = read_pgm(path);
  EXPECT_EQ(img.width, 3);
  EXPECT_EQ(img.height, 2);
  EXPECT_EQ(img.pixels[5], 'f');
}

TEST(Pgm, EachMalformedFileNamesTheProblem) {
  const auto dir = test::temp_dir("pgm_bad");
  auto check = [&](const std::string& name, const std::string& bytes, const std::string& expected) {
    const std::string path = (dir / name).string();
    write_raw(path, bytes);
    const std::string e = error_of(path);
    EXPECT_NE(e.find(expected), std::string::npos) << name << ": " << e;
  };
  check("magic.pgm", "P2\n2 2\n255\n1 2 3 4", "wrong magic 'P2'");
  check("empty.pgm", "", "wrong magic");
  check("trunc.pgm", "P5\n4 4\n255\nabc", "truncated: 3 of 16");
  check("trunc16.pgm", "P5\n4 4\n1000\n0123456789", "truncated: 10 of 32");
  check("zero.pgm", "P5\n0 4\n255\n", "size 0x4");
  check("huge.pgm", "P5\n100000 4\n255\n", "size 100000x4");
  check("maxval0.pgm", "P5\n2 2\n0\nabcd", "maxval 0");
  check("maxval_big.pgm", "P5\n2 2\n70000\nabcdefgh", "maxval 70000");
  check("noheight.pgm", "P5\n2 \n", "height");
  // A field runs to whitespace (found probing: "P564 64 255" read as width 64, "64.0" blamed on the height).
  check("glued_magic.pgm", "P564 2 255\nabcd", "no whitespace after the magic P5");
  check("fraction.pgm", "P5\n2.0 2\n255\nabcd", "header: width '2.0' is not a whole number in 1..16384");
  // A sign or more digits than any size: the value named (it said "missing or bad width").
  check("negative.pgm", "P5\n-64 2\n255\nabcd", "header: width '-64' is not a whole number in 1..16384");
  check("plus.pgm", "P5\n2 +64\n255\nabcd", "header: height '+64' is not a whole number in 1..16384");
  check("huge.pgm", "P5\n99999999999 2\n255\nabcd", "header: width '99999999999' is not a whole number in 1..16384");
  check("maxval.pgm", "P5\n2 2\n1000000000000\nabcd", "header: maxval '1000000000000' is not a whole number in 1..65535");
  check("short.pgm", "P5\n2 2\n", "header: maxval nothing is not a whole number in 1..65535");
  // Bytes beyond the raster: read as a wrong image without a word before.
  check("comment_after_maxval.pgm", "P5\n2 2\n255 # hand-made\nabcd", "12 bytes after the 2x2 raster");
  check("wide_under_255.pgm", "P5\n2 2\n255\nabcdefgh", "4 bytes after the 2x2 raster");
  check("two_images.pgm", "P5\n2 1\n255\nabP5\n2 1\n255\ncd", "after the 2x1 raster");
  // A sample above maxval: the header does not describe the data (read as it came before).
  check("above_maxval.pgm", "P5\n2 2\n100\nab\x10\xc8", "sample 200 at (1, 1) is above maxval 100");
  check("above_maxval16.pgm", std::string("P5\n2 1\n1000\n\x03\xe8\x03\xe9", 16), "sample 1001 at (1, 0) is above maxval 1000");
  const std::string missing = (dir / "missing.pgm").string();
  const std::string e = error_of(missing);
  EXPECT_NE(e.find("cannot open"), std::string::npos) << e;
}

}  // namespace
}  // namespace sempose::hal
