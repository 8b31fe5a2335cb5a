// Photos from disk into the centroider, the way centroid_targets reads them
// (io::ReadImageChecked, cv::IMREAD_UNCHANGED): a 16-bit PNG of a rendered
// ring target gives the centre of its 8-bit original (mono16 is measured at
// its own precision: the same levels x 257 measure the same), and a PNG
// whose header claims a huge image is refused before decoding with a
// message naming the file, its size and the limit.
#include <cstdio>
#include <fstream>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "design_renderer.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/image_file.h"

namespace slope_monitor {
namespace targets {
namespace {

const std::string kInputDir = ::testing::TempDir();

TEST(ImageFileInput, SixteenBitPngGivesTheEightBitCentre) {
  testing::DesignShotSpec spec;
  spec.design = CircleDesign::kRing;
  spec.centre_px = 30;
  const testing::DesignShot shot = testing::RenderDesignShot(spec);
  cv::Mat m16;
  shot.image.convertTo(m16, CV_16U, 257.0);
  const std::string p8 = kInputDir + "sm_ring8.png", p16 = kInputDir + "sm_ring16.png";
  ASSERT_TRUE(cv::imwrite(p8, shot.image));
  ASSERT_TRUE(cv::imwrite(p16, m16));
  const cv::Mat r8 = io::ReadImageChecked(p8, cv::IMREAD_UNCHANGED);
  const cv::Mat r16 = io::ReadImageChecked(p16, cv::IMREAD_UNCHANGED);
  ASSERT_EQ(r8.type(), CV_8UC1);
  ASSERT_EQ(r16.type(), CV_16UC1);
  Options o;
  o.families.clear();
  const TargetCentroider c(o, io::TargetList());
  const Result a = c.Detect(r8, "mono8"), b = c.Detect(r16, "mono16");
  ASSERT_EQ(a.observations.size(), 1u);
  ASSERT_EQ(b.observations.size(), 1u);
  EXPECT_LT((a.observations[0].centre - shot.truth).norm(), 0.02);
  EXPECT_NEAR((a.observations[0].centre - b.observations[0].centre).norm(), 0.0, 1e-6);
  // The wrong encoding for the data is named, not measured.
  EXPECT_THROW(c.Detect(r16, "mono8"), InvalidArgument);
  std::remove(p8.c_str());
  std::remove(p16.c_str());
}

// A PNG signature and an IHDR chunk (with its CRC) claiming w x h 8-bit grey.
void WritePngHeader(const std::string& path, uint32_t w, uint32_t h) {
  auto be32 = [](uint32_t v) {
    return std::string{static_cast<char>(v >> 24), static_cast<char>(v >> 16),
                       static_cast<char>(v >> 8), static_cast<char>(v)};
  };
  std::string ihdr = "IHDR" + be32(w) + be32(h) + std::string("\x08\x00\x00\x00\x00", 5);
  uint32_t crc = 0xffffffffu;
  for (unsigned char ch : ihdr) {
    crc ^= ch;
    for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xedb88320u & (0u - (crc & 1u)));
  }
  std::ofstream f(path, std::ios::binary);
  f << std::string("\x89PNG\r\n\x1a\n", 8) << be32(13) << ihdr << be32(~crc);
}

TEST(ImageFileInput, HugeImageHeaderIsRefusedBeforeDecoding) {
  const std::string path = kInputDir + "sm_huge.png";
  WritePngHeader(path, 60000, 60000);
  try {
    io::ReadImageChecked(path, cv::IMREAD_UNCHANGED);
    FAIL() << "a 3600 MP header was decoded";
  } catch (const IoError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(path), std::string::npos) << msg;
    EXPECT_NE(msg.find("60000 x 60000"), std::string::npos) << msg;
    EXPECT_NE(msg.find("max_megapixels"), std::string::npos) << msg;
  }
  std::remove(path.c_str());
}

}  // namespace
}  // namespace targets
}  // namespace slope_monitor
