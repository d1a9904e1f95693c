#pragma once
// PNG and JPEG files in and out, with libpng and libjpeg(-turbo) directly rather than OpenCV's
// imgcodecs: Debian's imgcodecs links ~80 more shared libraries (GDAL, DICOM, HEIF, OpenEXR, ...)
// whose loading and relocation cost every marglab process ~0.2 s at start-up, images or not.
//
// decodeImageFile gives what cv::imread(path, cv::IMREAD_UNCHANGED) gives for these formats (test/
// frontend checks it against imgcodecs pixel for pixel): 8- or 16-bit, 1 channel for grey, 3 (BGR
// order) for colour, 4 (BGRA) with alpha; PNG bit depths below 8 and palettes expanded, 16-bit
// samples in native byte order; no gamma or colour-profile conversion.

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace marglab {

// Throws InputError naming the file when it is not a readable PNG or JPEG.
cv::Mat decodeImageFile(const std::string& path);

// An 8-bit grey or BGR image as PNG file bytes (default zlib compression); throws
// std::runtime_error if libpng fails.
std::vector<uint8_t> encodePng(const cv::Mat& image);

}  // namespace marglab
