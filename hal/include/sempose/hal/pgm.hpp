// PGM (P5) reading and writing, 8- and 16-bit (16-bit samples big-endian, per the Netpbm
// spec). Small and strict, setup-time only.
//
// Errors: read_pgm/write_pgm throw std::runtime_error whose message names the file and the
// problem ("frames/f.pgm: truncated: 1000 of 4096 pixel bytes"); try_read_pgm returns false
// with the same text. Nothing is half-read: the output image is only assigned on success.
// Accepted: magic P5, comments (# to end of line) anywhere in the header, width and height in
// 1..16384, maxval in 1..65535 (> 255 means two bytes per sample). Image::bits is 8 when
// maxval <= 255, else 16; sample values are kept as stored (not rescaled to the maxval).
// Refused: bytes after the raster (a wrong maxval, a comment after maxval, a second image).
#pragma once

#include <string>
#include <vector>

#include "sempose/hal/image.hpp"

namespace sempose::hal {

inline constexpr int kPgmMaxSide = 16384;

Image read_pgm(const std::string& path);
bool try_read_pgm(const std::string& path, Image& out, std::string& error);
// The same rules for bytes already in memory (error without the file name); the fuzz target.
bool parse_pgm(const std::vector<unsigned char>& data, Image& out, std::string& error);
// Writes maxval 255 (bits 8, samples clamped to 255) or 65535 (bits 16).
void write_pgm(const std::string& path, const Image& image);

}  // namespace sempose::hal
