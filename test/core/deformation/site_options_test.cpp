// What a site file sets in the estimator: thresholds in SI units, aliases,
// the reports' geodetic origin or site CRS.
#include "slope_monitor/core/deformation/site_options.h"

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace deformation {
namespace {

TEST(SiteOptions, ShippedDemoSite) {
  const io::SiteFile site =
      io::LoadSiteFile(std::string(SM_SOURCE_DIR) + "/config/sites/demo.yaml");
  EstimatorOptions o;
  o.alerts.thresholds.watch = 1.0;  // overridden by the site
  ReportOptions r;
  ApplySite(site, &o, &r);
  EXPECT_DOUBLE_EQ(o.alerts.thresholds.watch, 2e-3 / 86400.0);  // 2 mm/day
  EXPECT_DOUBLE_EQ(o.alerts.thresholds.alarm, 50e-3 / 86400.0);
  EXPECT_EQ(o.aliases.at("tx1"), "tag36h11/10");
  EXPECT_EQ(o.aliases.at("tx5"), "tag36h11/12");
  ASSERT_TRUE(r.geodetic_origin.has_value());  // lat, lon, h of the simulator's origin
  EXPECT_NEAR((*r.geodetic_origin - Eigen::Vector3d(46.5, 8.0, 1200.0)).norm(), 0.0, 1e-9);
  EXPECT_FALSE(r.site_crs.has_value());  // local ENU: the reports as before, from the origin
}

TEST(SiteOptions, AbsentThresholdsKeptAndUnitsConverted) {
  const io::SiteFile site = io::ParseSiteFile(
      "name: x\ncrs: EPSG:32632\norigin: [500000, 5150000, 0]\nframe: shifted_crs\n"
      "thresholds: {unit: mm/h, alarm: 4}\n",
      "x.yaml", ".");
  EstimatorOptions o;
  const double watch = o.alerts.thresholds.watch;
  ReportOptions r;
  ApplySite(site, &o, &r);
  EXPECT_DOUBLE_EQ(o.alerts.thresholds.watch, watch);
  EXPECT_DOUBLE_EQ(o.alerts.thresholds.alarm, 4e-3 / 3600.0);  // 4 mm/h
  EXPECT_FALSE(r.geodetic_origin.has_value());  // a shifted CRS frame is not ENU at the origin
  // The reports are georeferenced in the site's own CRS (report_gis_test.cpp).
  ASSERT_TRUE(r.site_crs.has_value());
  EXPECT_EQ(r.site_crs->crs, "EPSG:32632");
  EXPECT_EQ(r.site_crs->origin, Eigen::Vector3d(500000, 5150000, 0));
  EXPECT_EQ(r.site_crs->frame, SiteCrsOptions::Frame::kShiftedCrs);
}

TEST(SiteOptions, AreaGrowthThresholds) {
  const io::SiteFile site = io::ParseSiteFile(
      "name: x\ncrs: EPSG:32632\norigin: [500000, 5150000, 0]\nframe: shifted_crs\n"
      "thresholds: {area_growth_warning: 400}\n",
      "x.yaml", ".");
  EstimatorOptions o;
  ReportOptions r;
  ApplySite(site, &o, &r);
  EXPECT_DOUBLE_EQ(o.areas.growth_watch, AreaOptions().growth_watch);  // absent: kept
  EXPECT_DOUBLE_EQ(o.areas.growth_warning, 400.0);
  EXPECT_THROW(io::ParseSiteFile("name: x\ncrs: EPSG:32632\norigin: [500000, 5150000, 0]\n"
                                 "frame: shifted_crs\n"
                                 "thresholds: {area_growth_watch: 50, area_growth_warning: 40}\n",
                                 "x.yaml", "."),
               Error);
}

}  // namespace
}  // namespace deformation
}  // namespace slope_monitor
