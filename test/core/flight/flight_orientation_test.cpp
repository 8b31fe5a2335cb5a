// Flight orientation (core/flight) on synthetic blocks with known truth: a
// nadir block of 3 strips x 6 photos over rolling terrain, a camera with
// strong barrel distortion that the nominal model (EXIF focal, no
// distortion) does not know, tie-point noise 0.3 px; georeferenced by noisy
// GNSS (2 m) or by control points picked in the photos (two of seven checks).
// Also the gcp_list.txt reader on hand-checkable text.
#include <cmath>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/flight/flight_orientation.h"
#include "slope_monitor/core/flight/flight_scene.h"
#include "slope_monitor/core/io/gcp_list.h"

namespace slope_monitor {
namespace flight {
namespace {

camera::CameraModel TruthCamera() {
  std::array<double, camera::kNumInterior> in{};
  in[camera::kC] = 10.3;  // EXIF says 10 mm
  in[camera::kX0] = 0.02;
  in[camera::kY0] = -0.015;
  in[camera::kK1] = -3e-4;  // 28 px at the corners
  return camera::CameraModel(camera::Sensor{3000, 2000, 0.004}, camera::DistortionModel::kRadial,
                             in);
}

double Terrain(double x, double y) { return 5.0 * std::sin(x / 30.0) + 3.0 * std::cos(y / 25.0); }

struct Synthetic {
  FlightPhotos photos;
  FlightTies ties;
  std::vector<camera::ExteriorOrientation> truth;
  std::vector<Eigen::Vector3d> gnss;
  std::vector<FlightControlPoint> control;
};

camera::ExteriorOrientation Nadir(const Eigen::Vector3d& centre, double heading) {
  // Looking down (photogrammetric camera z = site z), turned about the vertical.
  camera::ExteriorOrientation e;
  e.position = centre;
  e.angles.kappa = heading;
  return e;
}

Synthetic MakeBlock(unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> px_noise(0.0, 0.3), gnss_noise(0.0, 2.0), pick_noise(0.0, 0.5);
  std::uniform_real_distribution<double> ux(-60.0, 140.0), uy(-50.0, 150.0);
  Synthetic s;
  const camera::CameraModel truth = TruthCamera();
  std::array<double, camera::kNumInterior> nominal{};
  nominal[camera::kC] = 10.0;
  s.photos.nominal = camera::CameraModel(truth.sensor(), camera::DistortionModel::kNone, nominal);
  for (int strip = 0; strip < 3; ++strip) {
    for (int k = 0; k < 6; ++k) {
      const double y = strip % 2 ? 100.0 - 20.0 * k : 20.0 * k;  // flown both ways
      s.truth.push_back(
          Nadir({40.0 * strip, y, 100.0}, strip % 2 ? M_PI / 2 + 0.03 : M_PI / 2 - 0.02));
      FlightPhoto p;
      p.name = Message("P", strip, k, ".jpg");
      p.width = 3000;
      p.height = 2000;
      s.photos.photos.push_back(p);
      s.gnss.push_back(s.truth.back().position +
                       Eigen::Vector3d(gnss_noise(rng), gnss_noise(rng), gnss_noise(rng)));
    }
  }
  const int n = static_cast<int>(s.truth.size());
  auto observe = [&](const Eigen::Vector3d& x, double sigma_noise,
                     std::normal_distribution<double>& noise) {
    std::vector<std::pair<int, Eigen::Vector2d>> obs;
    for (int i = 0; i < n; ++i) {
      Eigen::Vector2d px;
      if (!truth.Project(s.truth[i], x, &px) || px.x() < 5 || px.y() < 5 || px.x() > 2994 ||
          px.y() > 1994)
        continue;
      obs.emplace_back(
          i, px + Eigen::Vector2d(noise(rng), noise(rng)) * (sigma_noise > 0 ? 1.0 : 0.0));
    }
    return obs;
  };
  for (int t = 0; t < 4000; ++t) {
    const double x = ux(rng), y = uy(rng);
    FlightTrack track;
    track.observations = observe({x, y, Terrain(x, y)}, 0.3, px_noise);
    if (track.observations.size() >= 2) s.ties.tracks.push_back(track);
  }
  for (int a = 0; a < n; ++a) {
    for (int b = a + 1; b < n; ++b) {
      FlightPairStats st{a, b, 0, 0.3, ""};
      for (const FlightTrack& t : s.ties.tracks) {
        bool ha = false, hb = false;
        for (const auto& o : t.observations) ha |= o.first == a, hb |= o.first == b;
        st.tie_points += ha && hb;
      }
      s.ties.pairs.push_back(st);
    }
  }
  const double gx[7] = {0, 80, 40, 10, 75, 80, 40}, gy[7] = {0, 0, 50, 100, 100, 50, 90};
  for (int g = 0; g < 7; ++g) {
    FlightControlPoint cp;
    cp.name = Message("gcp", g);
    cp.site = {gx[g], gy[g], Terrain(gx[g], gy[g])};
    cp.covariance = Eigen::Matrix3d::Identity() * 1e-4;
    cp.check = g == 4 || g == 6;
    cp.picks = observe(cp.site, 0.5, pick_noise);
    s.control.push_back(cp);
  }
  return s;
}

void ExpectWithinThreeSigma(const FlightResult& r, int index, double truth) {
  const double v = r.scene.cameras[0].model.interior()[index];
  const double sigma = r.summary.interior_sigma[index];
  EXPECT_GT(sigma, 0.0) << camera::InteriorNames()[index];
  EXPECT_LT(std::abs(v - truth), 3.0 * sigma)
      << camera::InteriorNames()[index] << " = " << v << " +- " << sigma << ", truth " << truth;
}

TEST(FlightOrientation, GnssBlockWithUnknownDistortionIsOrientedAndSelfCalibrated) {
  Synthetic s = MakeBlock(7);
  FlightInput in;
  in.photos = &s.photos;
  in.ties = &s.ties;
  for (const auto& g : s.gnss) in.gnss_in_site.emplace_back(g);
  const FlightResult r = OrientFlight(in);
  const FlightSummary& sum = r.summary;
  ASSERT_TRUE(sum.success) << sum.message;
  EXPECT_EQ(sum.oriented, 18);
  EXPECT_TRUE(sum.georeferenced);
  EXPECT_EQ(sum.datum, "GNSS of 18 photos");
  EXPECT_LT(sum.rms_px, 0.45);  // 0.3 px noise per coordinate: 0.42 px per point
  const auto& interior = r.scene.cameras[0].model.interior();
  EXPECT_NEAR(interior[camera::kK1], -3e-4, 0.1 * 3e-4);
  // c trades off against the depth of gently rolling ground seen from above:
  // GNSS on the camera centres alone determine it weakly; its sigma must say so.
  ExpectWithinThreeSigma(r, camera::kC, 10.3);
  for (size_t i = 0; i < r.scene.images.size(); ++i) {
    const Eigen::Vector3d d =
        r.scene.images[i].exterior.position - s.truth[r.photo_of_image[i]].position;
    EXPECT_LT(d.head<2>().norm(), 1.5) << r.scene.images[i].name;  // GNSS 2 m each, 18 of them
  }
}

// Pairwise tracks (each ground point as the two-photo pieces a pair gives,
// as when the pairs' tie points start at nearby but different interest
// points) leave every photo but the start pair without known points; the
// growth tracks (the pieces joined) orient the block, and the adjustment
// keeps the pieces.
TEST(FlightOrientation, GrowthTracksOrientTheBlockAndTheAdjustmentKeepsThePairwiseTracks) {
  Synthetic s = MakeBlock(7);
  FlightTies pieces = s.ties;
  pieces.tracks.clear();
  for (const FlightTrack& t : s.ties.tracks)
    for (size_t k = 0; k + 1 < t.observations.size(); ++k)
      pieces.tracks.push_back(FlightTrack{{t.observations[k], t.observations[k + 1]}, t.grey});
  FlightInput in;
  in.photos = &s.photos;
  in.ties = &pieces;
  for (const auto& g : s.gnss) in.gnss_in_site.emplace_back(g);
  const FlightResult alone = OrientFlight(in);
  EXPECT_LE(alone.summary.oriented, 2);  // the start pair at most

  pieces.growth_tracks = s.ties.tracks;
  const FlightResult r = OrientFlight(in);
  ASSERT_TRUE(r.summary.success) << r.summary.message;
  EXPECT_EQ(r.summary.oriented, 18);
  EXPECT_LT(r.summary.rms_px, 0.45);  // 0.3 px noise per coordinate
  EXPECT_GT(r.summary.points, static_cast<int>(s.ties.tracks.size()));  // the pieces
  for (size_t i = 0; i < r.scene.images.size(); ++i) {
    const Eigen::Vector3d d =
        r.scene.images[i].exterior.position - s.truth[r.photo_of_image[i]].position;
    EXPECT_LT(d.head<2>().norm(), 1.5) << r.scene.images[i].name;
  }
}

TEST(FlightOrientation, ControlPointsPickedInPhotosGiveTheDatumAndCheckPointsStayOut) {
  Synthetic s = MakeBlock(11);
  FlightInput in;
  in.photos = &s.photos;
  in.ties = &s.ties;
  in.control = s.control;
  const FlightResult r = OrientFlight(in);
  const FlightSummary& sum = r.summary;
  ASSERT_TRUE(sum.success) << sum.message;
  EXPECT_EQ(sum.oriented, 18);
  EXPECT_EQ(sum.datum, "5 control points");
  ASSERT_EQ(sum.check.size(), 2u);
  for (const PointResidual& c : sum.check) {
    ASSERT_TRUE(c.measured) << c.name << ": " << c.message;
    EXPECT_LT(c.residual.norm(), 0.15) << c.name;  // ground pixel 4 cm
  }
  ASSERT_EQ(sum.control.size(), 5u);  // checks never in the adjustment
  for (const PointResidual& c : sum.control)
    EXPECT_TRUE(c.name != "gcp4" && c.name != "gcp6") << c.name;
  EXPECT_EQ(sum.check[0].name, "gcp4");
  for (const PointResidual& c : sum.control)
    EXPECT_LT(c.pick_rms_px, 2.0) << c.name;  // picks 0.5 px noise
  ASSERT_EQ(sum.leave_one_out.size(), 5u);
  EXPECT_LT(sum.leave_one_out_rms, 0.3);
  ExpectWithinThreeSigma(r, camera::kC, 10.3);
  for (size_t i = 0; i < r.scene.images.size(); ++i) {
    const Eigen::Vector3d d =
        r.scene.images[i].exterior.position - s.truth[r.photo_of_image[i]].position;
    // The principal point and the horizontal centre trade off on a nadir
    // block (the ground stays right: the check points above); the
    // adjustment's sigma must cover it.
    const auto& cov = r.bundle.precision.exterior_covariance.at(i);
    EXPECT_LT(std::abs(d.x()), 3.0 * std::sqrt(cov(0, 0)) + 0.05) << r.scene.images[i].name;
    EXPECT_LT(std::abs(d.y()), 3.0 * std::sqrt(cov(1, 1)) + 0.05) << r.scene.images[i].name;
    // The height above ground over c (the image scale) is what the photos
    // fix; c and the height trade off along it.
    const double c = r.scene.cameras[0].model.interior()[camera::kC];
    EXPECT_NEAR(r.scene.images[i].exterior.position.z() / c, 100.0 / 10.3, 0.01 * 100.0 / 10.3);
  }
}

TEST(FlightOrientation, WithoutDatumTheBlockStaysInItsModelFrameAndSaysSo) {
  Synthetic s = MakeBlock(3);
  FlightInput in;
  in.photos = &s.photos;
  in.ties = &s.ties;
  const FlightResult r = OrientFlight(in);
  ASSERT_TRUE(r.summary.success) << r.summary.message;
  EXPECT_EQ(r.summary.oriented, 18);
  EXPECT_FALSE(r.summary.georeferenced);
  EXPECT_NE(r.summary.datum.find("model frame"), std::string::npos) << r.summary.datum;
  EXPECT_LT(r.summary.rms_px, 0.45);
}

TEST(FlightOrientation, NoTiePointsNoStartPair) {
  Synthetic s = MakeBlock(5);
  s.ties.tracks.clear();
  for (auto& p : s.ties.pairs) p.tie_points = 0;
  FlightInput in;
  in.photos = &s.photos;
  in.ties = &s.ties;
  const FlightResult r = OrientFlight(in);
  EXPECT_FALSE(r.summary.success);
  EXPECT_NE(r.summary.message.find("no start pair"), std::string::npos) << r.summary.message;
  EXPECT_EQ(r.summary.not_oriented.size(), 18u);
}

// The synthetic block as the graph collects it: camera `drone` (appended
// to the scene's cameras), one image per photo with its GNSS prior (2 m),
// the tracks as tie points, all unknown.
void AddDroneEpoch(const Synthetic& s, const adjustment::Camera& drone, adjustment::Scene* scene) {
  const int cam = static_cast<int>(scene->cameras.size());
  scene->cameras.push_back(drone);
  const int first_image = static_cast<int>(scene->images.size());
  for (size_t i = 0; i < s.photos.photos.size(); ++i) {
    adjustment::Image im;
    im.name = "drone@" + std::to_string(i);
    im.camera = cam;
    im.exterior_known = false;
    im.position_prior = s.gnss[i];
    im.position_prior_covariance = Eigen::Matrix3d::Identity() * 4.0;
    scene->images.push_back(im);
  }
  for (size_t t = 0; t < s.ties.tracks.size(); ++t) {
    adjustment::ObjectPoint p;
    p.id = "tie/" + std::to_string(t);
    p.position_known = false;
    const int point = static_cast<int>(scene->points.size());
    scene->points.push_back(p);
    for (const auto& [photo, px] : s.ties.tracks[t].observations)
      scene->observations.push_back(
          {first_image + photo, point, px, Eigen::Matrix2d::Identity() * 0.09});
  }
}

// The graph's form: a collected epoch's scene of a UAV camera "drone" with
// tie points and GNSS priors (plus a fixed camera that must stay untouched).
TEST(FlightScene, AUavEpochWithoutTargetsIsStartedFromItsTiePoints) {
  Synthetic s = MakeBlock(13);
  adjustment::Scene scene;
  scene.cameras.push_back({"fixed_1", TruthCamera()});
  AddDroneEpoch(s, {"drone", s.photos.nominal}, &scene);
  const FlightSummary sum = OrientSceneFromTiePoints(&scene, "drone");
  ASSERT_TRUE(sum.success) << sum.message;
  EXPECT_EQ(sum.oriented, 18);
  EXPECT_EQ(sum.datum, "GNSS of 18 photos");
  int known = 0;
  for (const auto& p : scene.points) known += p.position_known;
  EXPECT_GT(known, static_cast<int>(scene.points.size()) * 9 / 10);
  for (size_t i = 0; i < scene.images.size(); ++i) {
    EXPECT_TRUE(scene.images[i].exterior_known);
    EXPECT_LT((scene.images[i].exterior.position - s.truth[i].position).head<2>().norm(), 3.0)
        << i;  // GNSS 2 m
  }
  EXPECT_EQ(scene.cameras[1].model.model(), camera::DistortionModel::kRadial);
  EXPECT_NEAR(scene.cameras[1].model.interior()[camera::kK1], -3e-4, 0.1 * 3e-4);
  EXPECT_EQ(scene.cameras[0].model.interior()[camera::kC], 10.3);  // the other camera untouched
  EXPECT_THROW(OrientSceneFromTiePoints(&scene, "uav"), InvalidArgument);
}

// A calibrated camera with decentring terms (brown) keeps its model.
TEST(FlightScene, ACalibratedCameraKeepsItsDistortionModel) {
  Synthetic s = MakeBlock(17);
  std::array<double, camera::kNumInterior> in = TruthCamera().interior();
  in[camera::kP1] = 6e-6;
  adjustment::Scene scene;
  AddDroneEpoch(
      s,
      {"drone", camera::CameraModel(TruthCamera().sensor(), camera::DistortionModel::kBrown, in)},
      &scene);
  const FlightSummary sum = OrientSceneFromTiePoints(&scene, "drone");
  ASSERT_TRUE(sum.success) << sum.message;
  EXPECT_EQ(sum.oriented, 18);
  EXPECT_EQ(scene.cameras[0].model.model(), camera::DistortionModel::kBrown);
}

std::string WriteText(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + name;
  std::ofstream(path) << text;
  return path;
}

TEST(GcpList, ReadsOdmFormatWithNamedPoints) {
  const std::string path =
      WriteText("gcp_ok.txt",
                "WGS84 UTM 11N\n"
                "235269.88\t3811198.11\t0.0\t3609.37\t2293.79\tIMG_0037.jpg\tgcp02\n"
                "# a comment\n"
                "235269.88 3811198.11 0.0 589.69 1026.48 IMG_0121.jpg gcp02\n"
                "235262.54 3811203.5 1.5 3472.18 1000.56 IMG_0052.jpg\n");
  const io::GcpList list = io::ReadGcpList(path);
  EXPECT_EQ(list.crs, "EPSG:32611");
  ASSERT_EQ(list.points.size(), 2u);
  EXPECT_EQ(list.points[0].name, "gcp02");
  ASSERT_EQ(list.points[0].picks.size(), 2u);
  EXPECT_EQ(list.points[0].picks[1].image, "IMG_0121.jpg");
  EXPECT_EQ(list.points[0].picks[1].line, 4);
  EXPECT_DOUBLE_EQ(list.points[0].picks[1].pixel.x(), 589.69);
  EXPECT_EQ(list.points[1].name, "line5");
  EXPECT_DOUBLE_EQ(list.points[1].geo.z(), 1.5);
  EXPECT_EQ(io::NormaliseGcpCrs("+proj=utm +zone=11 +ellps=WGS84 +datum=WGS84 +units=m +no_defs"),
            "EPSG:32611");
  EXPECT_EQ(io::NormaliseGcpCrs("+proj=utm +zone=54 +south +datum=WGS84"), "EPSG:32754");
  EXPECT_EQ(io::NormaliseGcpCrs("+proj=tmerc +lat_0=36 +lon_0=139.83 +k=0.9999 +ellps=GRS80"),
            "+proj=tmerc +lat_0=36 +lon_0=139.83 +k=0.9999 +ellps=GRS80 +type=crs");
  EXPECT_EQ(io::NormaliseGcpCrs("WGS84 UTM 33S"), "EPSG:32733");
}

TEST(GcpList, BadLinesAreNamedByFileAndLine) {
  auto message = [](const std::string& text) {
    try {
      io::ReadGcpList(WriteText("gcp_bad.txt", text));
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("EPSG:32611\n1 2 3 4 5\n").find("gcp_bad.txt:2: 5 fields"), std::string::npos);
  EXPECT_NE(
      message("EPSG:32611\n1 2 x 4 5 a.jpg\n").find("gcp_bad.txt:2: geo_z 'x' is not a number"),
      std::string::npos);
  EXPECT_NE(message("EPSG:32611\n1 2 3 4 5 a.jpg p\n1 2 4 4 5 b.jpg p\n")
                .find("other coordinates than on line 2"),
            std::string::npos);
  EXPECT_NE(
      message("EPSG:32611\n1 2 3 4 5 a.jpg p\n1 2 3 6 7 a.jpg p\n").find("picked in 'a.jpg' again"),
      std::string::npos);
  EXPECT_NE(message("").find("empty"), std::string::npos);
  EXPECT_NE(message("EPSG:32611\n").find("no picks"), std::string::npos);
  EXPECT_THROW(io::ReadGcpList("/nonexistent/gcp_list.txt"), IoError);
}

}  // namespace
}  // namespace flight
}  // namespace slope_monitor
