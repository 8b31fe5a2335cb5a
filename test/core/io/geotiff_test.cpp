#include "slope_monitor/core/io/geotiff.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <unistd.h>

#include <gdal_priv.h>
#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/site_crs.h"
#include "slope_monitor/core/io/map_raster.h"

namespace slope_monitor {
namespace io {
namespace {

namespace fs = std::filesystem;

class GeoTiffTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("geotiff_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

// A 5 x 3 raster (width 5 east, height 3 north) at 0.5 m cells whose
// north-west corner is (10, 20): cell (row 2, col 4) centres at
// (10 + 4.5 * 0.5, 20 - 2.5 * 0.5) = (12.25, 18.75).
GeoRaster MakeRaster() {
  GeoRaster r(5, 3, 10.0, 20.0, 0.5);
  r.AddBand("height");
  r.AddBand("sigma", 0.25f);
  for (int row = 0; row < 3; ++row)
    for (int col = 0; col < 5; ++col) r.At(0, row, col) = 100.0f + 10.0f * row + col;
  r.At(0, 1, 2) = static_cast<float>(r.nodata);  // a hole
  return r;
}

TEST_F(GeoTiffTest, RoundTripKeepsValuesBandsAndNoData) {
  const GeoRaster r = MakeRaster();
  WriteGeoTiff(Path("a.tif"), r);
  const GeoRaster b = ReadGeoTiff(Path("a.tif"));
  ASSERT_EQ(b.width, 5);
  ASSERT_EQ(b.height, 3);
  ASSERT_EQ(b.num_bands(), 2);
  EXPECT_EQ(b.band_names[0], "height");
  EXPECT_EQ(b.band_names[1], "sigma");
  EXPECT_EQ(b.BandIndex("sigma"), 1);
  EXPECT_TRUE(std::isnan(b.nodata));
  for (int row = 0; row < 3; ++row)
    for (int col = 0; col < 5; ++col) {
      if (row == 1 && col == 2) {
        EXPECT_TRUE(b.IsNoData(b.At(0, row, col)));
      } else {
        EXPECT_FLOAT_EQ(b.At(0, row, col), 100.0f + 10.0f * row + col);
      }
      EXPECT_FLOAT_EQ(b.At(1, row, col), 0.25f);
    }
  // No temporary file is left behind.
  int files = 0;
  for (const auto& e : fs::directory_iterator(dir_)) files += e.is_regular_file();
  EXPECT_EQ(files, 1);
}

// An orthophoto (rgb): an 8-bit RGB GeoTIFF with an alpha band, as GIS
// tools expect a picture (GDAL itself checks the file), and read back as
// three bands with the hole as nodata and the values rounded to bytes.
TEST_F(GeoTiffTest, RgbPictureIsWrittenAsBytesWithAlpha) {
  GeoRaster r(4, 2, 10.0, 20.0, 0.5);
  r.epsg = 32632;
  r.rgb = true;
  for (const char* name : {"red", "green", "blue"}) r.AddBand(name, 0.0f);
  r.At(0, 0, 0) = 12.4f;                         // -> 12
  r.At(1, 0, 0) = 254.6f;                        // -> 255
  r.At(2, 0, 0) = 300.0f;                        // clamped to 255
  r.At(1, 1, 3) = static_cast<float>(r.nodata);  // a hole in one band: transparent
  WriteGeoTiff(Path("ortho.tif"), r);

  GDALAllRegister();
  GDALDataset* ds = static_cast<GDALDataset*>(GDALOpen(Path("ortho.tif").c_str(), GA_ReadOnly));
  ASSERT_NE(ds, nullptr);
  ASSERT_EQ(ds->GetRasterCount(), 4);
  const GDALColorInterp expected[4] = {GCI_RedBand, GCI_GreenBand, GCI_BlueBand, GCI_AlphaBand};
  for (int b = 0; b < 4; ++b) {
    EXPECT_EQ(ds->GetRasterBand(b + 1)->GetRasterDataType(), GDT_Byte) << "band " << b + 1;
    EXPECT_EQ(ds->GetRasterBand(b + 1)->GetColorInterpretation(), expected[b]) << "band " << b + 1;
  }
  GByte alpha[8];
  ASSERT_EQ(ds->GetRasterBand(4)->RasterIO(GF_Read, 0, 0, 4, 2, alpha, 4, 2, GDT_Byte, 0, 0),
            CE_None);
  for (int i = 0; i < 8; ++i) EXPECT_EQ(alpha[i], i == 7 ? 0 : 255) << "cell " << i;
  GDALClose(ds);

  const GeoRaster b = ReadGeoTiff(Path("ortho.tif"));
  EXPECT_TRUE(b.rgb);
  ASSERT_EQ(b.num_bands(), 3);
  EXPECT_EQ(b.band_names, (std::vector<std::string>{"red", "green", "blue"}));
  EXPECT_EQ(b.epsg, 32632);
  EXPECT_FLOAT_EQ(b.At(0, 0, 0), 12.0f);
  EXPECT_FLOAT_EQ(b.At(1, 0, 0), 255.0f);
  EXPECT_FLOAT_EQ(b.At(2, 0, 0), 255.0f);
  for (int band = 0; band < 3; ++band) EXPECT_TRUE(b.IsNoData(b.At(band, 1, 3)));
  EXPECT_FLOAT_EQ(b.At(0, 1, 2), 0.0f);

  r.bands.pop_back();  // two bands cannot be a picture
  r.band_names.pop_back();
  EXPECT_THROW(WriteGeoTiff(Path("two.tif"), r), InvalidArgument);
}

TEST_F(GeoTiffTest, GeoTransformAndCellCentres) {
  WriteGeoTiff(Path("g.tif"), MakeRaster());
  const GeoRaster b = ReadGeoTiff(Path("g.tif"));
  EXPECT_DOUBLE_EQ(b.origin_x, 10.0);
  EXPECT_DOUBLE_EQ(b.origin_y, 20.0);
  EXPECT_DOUBLE_EQ(b.cell_size, 0.5);
  const std::vector<double> gt = b.GeoTransform();
  EXPECT_DOUBLE_EQ(gt[5], -0.5);
  const Eigen::Vector2d c = b.CellCentre(2, 4);
  EXPECT_DOUBLE_EQ(c.x(), 12.25);
  EXPECT_DOUBLE_EQ(c.y(), 18.75);
  int row = -1, col = -1;
  ASSERT_TRUE(b.CellOf(12.3, 18.6, &row, &col));
  EXPECT_EQ(row, 2);
  EXPECT_EQ(col, 4);
  EXPECT_FALSE(b.CellOf(9.99, 19.0, &row, &col));
  EXPECT_FALSE(b.CellOf(11.0, 20.01, &row, &col));
  // Between the centres of (0,0)=100 and (0,1)=101: 100.5.
  EXPECT_NEAR(b.Interpolate(0, 10.5, 19.75), 100.5, 1e-6);
  // Next to the hole: NaN, never a silently filled value.
  EXPECT_TRUE(std::isnan(b.Interpolate(0, 11.1, 19.1)));
  // Local CRS named "site" when no EPSG code is given.
  EXPECT_EQ(b.epsg, 0);
  EXPECT_NE(b.srs_wkt.find("site"), std::string::npos) << b.srs_wkt;
}

TEST_F(GeoTiffTest, FiniteNoDataAndEpsg) {
  GeoRaster r(2, 2, 500000.0, 4000000.0, 2.0);
  r.nodata = -9999.0;
  r.epsg = 32654;  // WGS 84 / UTM zone 54N
  r.AddBand("z");
  r.At(0, 0, 0) = 1.5f;
  WriteGeoTiff(Path("u.tif"), r);
  const GeoRaster b = ReadGeoTiff(Path("u.tif"));
  EXPECT_DOUBLE_EQ(b.nodata, -9999.0);
  EXPECT_EQ(b.epsg, 32654);
  EXPECT_FLOAT_EQ(b.At(0, 0, 0), 1.5f);
  EXPECT_FLOAT_EQ(b.At(0, 1, 1), -9999.0f);
  EXPECT_TRUE(b.IsNoData(b.At(0, 1, 1)));
  EXPECT_FALSE(b.IsNoData(b.At(0, 0, 0)));
}

TEST_F(GeoTiffTest, BadPathNamesTheFile) {
  const std::string bad = Path("no_such_dir/x.tif");
  try {
    WriteGeoTiff(bad, MakeRaster());
    FAIL() << "no exception";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(bad));
  try {
    ReadGeoTiff(Path("missing.tif"));
    FAIL() << "no exception";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.tif"), std::string::npos) << e.what();
  }
  // A file that is not a raster.
  {
    std::FILE* f = std::fopen(Path("junk.tif").c_str(), "w");
    std::fputs("not a tiff", f);
    std::fclose(f);
  }
  EXPECT_THROW(ReadGeoTiff(Path("junk.tif")), IoError);
}

TEST_F(GeoTiffTest, InconsistentRasterIsRejectedBeforeWriting) {
  GeoRaster r = MakeRaster();
  r.bands[1].pop_back();
  EXPECT_THROW(WriteGeoTiff(Path("bad.tif"), r), InvalidArgument);
  r = MakeRaster();
  r.cell_size = 0.0;
  EXPECT_THROW(WriteGeoTiff(Path("bad.tif"), r), InvalidArgument);
  EXPECT_FALSE(fs::exists(Path("bad.tif")));
  // An existing valid file is not replaced by a failed write.
  WriteGeoTiff(Path("keep.tif"), MakeRaster());
  EXPECT_THROW(WriteGeoTiff(Path("keep.tif"), r), InvalidArgument);
  EXPECT_EQ(ReadGeoTiff(Path("keep.tif")).width, 5);
}

// A site raster for the map CRS tests: 100 x 80 cells of 1 m, corner
// (-50, 40), a plane z = 10 + 0.1 x + 0.05 y and a categorical band (the
// column number).
GeoRaster PlaneInSite() {
  GeoRaster r(100, 80, -50.0, 40.0, 1.0);
  r.AddBand("height");
  r.AddBand("count", 0.0f);
  for (int row = 0; row < r.height; ++row)
    for (int col = 0; col < r.width; ++col) {
      const Eigen::Vector2d xy = r.CellCentre(row, col);
      r.At(0, row, col) = static_cast<float>(10.0 + 0.1 * xy.x() + 0.05 * xy.y());
      r.At(1, row, col) = static_cast<float>(col);
    }
  return r;
}

// A shifted_crs site (JGD2011 zone IX, EPSG:6677): the same cells, the corner
// and the heights moved by the origin, nothing resampled.
TEST_F(GeoTiffTest, ShiftedCrsSiteRasterIsTheSameCellsMovedByTheOrigin) {
  SiteCrsOptions o;
  o.crs = "EPSG:6677";
  o.origin = {-21000.0, -11000.0, 120.0};
  o.frame = SiteCrsOptions::Frame::kShiftedCrs;
  const SiteCrs site(o);
  const GeoRaster r = PlaneInSite();
  WriteGeoTiff(Path("shifted.tif"), MapRasterFromSite(r, &site));
  const GeoRaster m = ReadGeoTiff(Path("shifted.tif"));
  EXPECT_EQ(m.epsg, 6677);
  EXPECT_EQ(m.width, 100);
  EXPECT_EQ(m.height, 80);
  EXPECT_DOUBLE_EQ(m.origin_x, -21050.0);
  EXPECT_DOUBLE_EQ(m.origin_y, -10960.0);
  EXPECT_NEAR(m.At(0, 0, 0), 120.0 + 10.0 + 0.1 * -49.5 + 0.05 * 39.5, 1e-4);
  const GeoRaster back = SiteRasterFromMap(m, &site, r);
  for (size_t i = 0; i < r.bands[0].size(); ++i) {
    ASSERT_NEAR(back.bands[0][i], r.bands[0][i], 1e-4) << i;
    ASSERT_EQ(back.bands[1][i], r.bands[1][i]) << i;
  }
}

// A local_enu site at 46.5 N 8.0 E, 1200 m (the simulated sites): the
// raster in UTM zone 32 (EPSG:32632) on a north-up grid turned by the
// meridian convergence (0.725 deg: the 100 x 80 m site raster needs about
// 100 cos g + 80 sin g = 101.0 by 80 cos g + 100 sin g = 81.3 cells, plus a
// cell of rounding), heights ellipsoidal (1200 m + z within the tangent
// plane's 1 mm at 60 m; the edge cells their own value), and back in the site frame: the plane
// within 1 mm where bilinear (cells inside), the categorical band a cell's own value.
TEST_F(GeoTiffTest, LocalEnuSiteRasterGoesToTheUtmZoneOfItsOriginAndBack) {
  const SiteCrs site = SiteCrs::LocalEnuAtWgs84(46.5, 8.0, 1200.0);
  const GeoRaster r = PlaneInSite();
  WriteGeoTiff(Path("utm.tif"), MapRasterFromSite(r, &site));
  const GeoRaster m = ReadGeoTiff(Path("utm.tif"));
  EXPECT_EQ(m.epsg, 32632);
  EXPECT_GE(m.width, 101);
  EXPECT_LE(m.width, 103);
  EXPECT_GE(m.height, 81);
  EXPECT_LE(m.height, 83);
  int heights = 0;
  for (int row = 0; row < m.height; ++row)
    for (int col = 0; col < m.width; ++col) {
      const float h = m.At(0, row, col);
      if (m.IsNoData(h)) continue;
      const Eigen::Vector2d c = m.CellCentre(row, col);
      const Eigen::Vector3d s = site.SiteFromMap(Eigen::Vector3d(c.x(), c.y(), 1200.0));
      // Between the outer cell centres bilinear, outside them the edge
      // cell's value (off the plane by up to half a cell: 0.075 m).
      const bool inside = std::abs(s.x()) <= 49.5 && std::abs(s.y()) <= 39.5;
      ASSERT_NEAR(h, 1200.0 + 10.0 + 0.1 * s.x() + 0.05 * s.y(), inside ? 0.002 : 0.076)
          << row << " " << col;
      ++heights;
    }
  EXPECT_GT(heights, 0.97 * 100 * 80);  // the edges kept (nearest cell)
  const GeoRaster back = SiteRasterFromMap(m, &site, r);
  int checked = 0;
  for (int row = 2; row < r.height - 2; ++row)
    for (int col = 2; col < r.width - 2; ++col) {
      ASSERT_NEAR(back.At(0, row, col), r.At(0, row, col), 0.001) << row << " " << col;
      const float k = back.At(1, row, col);
      ASSERT_EQ(k, std::round(k));
      ASSERT_LE(std::abs(k - col), 1.0f) << row << " " << col;
      ++checked;
    }
  EXPECT_EQ(checked, 96 * 76);
  // Without a georeference: the local CRS, the raster as it is.
  EXPECT_EQ(MapRasterFromSite(r, nullptr).epsg, 0);
  EXPECT_THROW(SiteRasterFromMap(m, nullptr, r), InvalidArgument);
}

}  // namespace
}  // namespace io
}  // namespace slope_monitor
