// core/frontend/image_file.h against OpenCV's own codecs (imgcodecs, linked by this test only):
// decodeImageFile gives what cv::imread(path, IMREAD_UNCHANGED) gives, pixel for pixel, on the
// shipped real EuRoC frames and on images of every layout the decoder handles (grey 1 / 8 / 16 bit,
// colour 8 / 16 bit, alpha, grey, colour and progressive JPEG); encodePng round-trips through
// cv::imdecode; truncated and foreign files are input errors naming the file.

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/temp_dir.h"
#include "core/common/error.h"
#include "core/common/source_dir.h"
#include "core/frontend/image_file.h"

namespace marglab {
namespace {

namespace fs = std::filesystem;

bool samePixels(const cv::Mat& a, const cv::Mat& b) {
  return a.type() == b.type() && a.size() == b.size() &&
         (a.empty() || cv::norm(a, b, cv::NORM_INF) == 0);
}

class ImageFile : public test::TempDirTest {
 protected:
  // Writes `image` with imgcodecs and checks that both decoders read back the same pixels.
  void expectSameAsImread(const std::string& name, const cv::Mat& image,
                          const std::vector<int>& params = {}) {
    const std::string path = (dir_ / name).string();
    ASSERT_TRUE(cv::imwrite(path, image, params)) << name;
    const cv::Mat expected = cv::imread(path, cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(expected.empty()) << name;
    const cv::Mat decoded = decodeImageFile(path);
    EXPECT_TRUE(samePixels(decoded, expected))
        << name << ": type " << decoded.type() << " vs " << expected.type();
  }

  cv::Mat random(int type) const {
    cv::Mat image(37, 53, type);
    cv::RNG rng(7);
    rng.fill(image, cv::RNG::UNIFORM, 0, CV_MAT_DEPTH(type) == CV_16U ? 65536 : 256);
    return image;
  }
};

TEST_F(ImageFile, ShippedEurocFramesDecodeAsImread) {
  const fs::path data = fs::path(sourceDir()) / "datasets/euroc/V1_01_easy_images/mav0/cam1/data";
  int n = 0;
  for (const auto& entry : fs::directory_iterator(data)) {
    if (n++ == 5) break;
    const cv::Mat expected = cv::imread(entry.path().string(), cv::IMREAD_UNCHANGED);
    const cv::Mat decoded = decodeImageFile(entry.path().string());
    EXPECT_EQ(decoded.type(), CV_8UC1);
    EXPECT_EQ(decoded.size(), cv::Size(752, 480));
    EXPECT_TRUE(samePixels(decoded, expected)) << entry.path();
  }
  EXPECT_EQ(n, 6);
}

TEST_F(ImageFile, EveryPngLayoutDecodesAsImread) {
  expectSameAsImread("grey8.png", random(CV_8UC1));
  expectSameAsImread("grey16.png", random(CV_16UC1));
  expectSameAsImread("bgr8.png", random(CV_8UC3));
  expectSameAsImread("bgr16.png", random(CV_16UC3));
  expectSameAsImread("bgra8.png", random(CV_8UC4));
  cv::Mat bilevel = random(CV_8UC1);
  cv::threshold(bilevel, bilevel, 127, 255, cv::THRESH_BINARY);
  expectSameAsImread("grey1.png", bilevel, {cv::IMWRITE_PNG_BILEVEL, 1});
}

TEST_F(ImageFile, JpegDecodesAsImread) {
  expectSameAsImread("grey.jpg", random(CV_8UC1), {cv::IMWRITE_JPEG_QUALITY, 90});
  expectSameAsImread("colour.jpg", random(CV_8UC3), {cv::IMWRITE_JPEG_QUALITY, 90});
  expectSameAsImread("progressive.jpg", random(CV_8UC3), {cv::IMWRITE_JPEG_PROGRESSIVE, 1});
}

TEST_F(ImageFile, EncodePngRoundTrips) {
  for (const int type : {CV_8UC1, CV_8UC3}) {
    const cv::Mat image = random(type);
    const std::vector<uint8_t> png = encodePng(image);
    EXPECT_TRUE(samePixels(cv::imdecode(png, cv::IMREAD_UNCHANGED), image)) << type;
  }
  EXPECT_THROW(encodePng(random(CV_16UC1)), std::invalid_argument);
}

TEST_F(ImageFile, TruncatedOrForeignFilesAreInputErrorsNamingTheFile) {
  const std::string good = (dir_ / "good.png").string();
  ASSERT_TRUE(cv::imwrite(good, random(CV_8UC1)));
  const auto size = fs::file_size(good);
  const std::string truncated = (dir_ / "truncated.png").string();
  fs::copy_file(good, truncated);
  fs::resize_file(truncated, size / 2);
  const std::string text = (dir_ / "text.png").string();
  std::ofstream(text) << "not an image";
  const std::string empty = (dir_ / "empty.png").string();
  std::ofstream{empty};
  for (const std::string& path : {truncated, text, empty, (dir_ / "missing.png").string()}) {
    try {
      decodeImageFile(path);
      ADD_FAILURE() << path << " decoded";
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), path);
    }
  }
}

}  // namespace
}  // namespace marglab
