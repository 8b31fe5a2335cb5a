// dense_surface: offline dense surface measurement of an oriented image pair
// (the dense_matcher nodelet's core), its orthophoto, and the change against
// a reference surface.
//
// Pair from files (camera models and orientations in a YAML file):
//   dense_surface --pair pair.yaml --out-dir DIR [--config config/defaults/dense_matcher.yaml]
//                 [--reference DIR_OR_FILE_surface.tif] [--site SITE.yaml | --site-config
//                 OVERLAY.yaml]
//   pair.yaml:
//     left:  {image: l.png, sensor: [width, height, pixel_size_mm], distortion_model: brown,
//             interior: [c, x0, y0, k1, k2, k3, p1, p2, b1, b2], exterior: [X0, Y0, Z0, theta, phi,
//             kappa]}
//     right: {...}
//
// Pair from a simulated survey, with the simulator's TRUE orientation and the
// truth comparison (doc/simulator.md):
//   dense_surface --truth demo.truth.yaml --bag demo.bag [--left-camera NAME]
//                 [--right-camera NAME] --epoch 1 [--reference-epoch 0] --out-dir DIR
//                 [--config ...]
//   (the cameras default to the truth's first and second camera of kind fixed)
//   prints the height error against demo.surface_eNN.tif (RMS and 95th
//   percentile on bare ground, and near the scarp / obstacles separately) and,
//   with --reference-epoch, the measured cut-and-fill against the true one.
//
// Every epoch of a bag, with the bag's ADJUSTED orientations (the bundle
// adjuster's /bundle_adjuster/solution, as recorded by record.launch or
// written by process_bag --output-bag): no depth is guessed, the ground comes
// from the adjusted points (doc/dense_change.md):
//   dense_surface --bag run.bag --out-dir DIR [--config config/defaults/dense_epoch.yaml]
//                 [--epoch K] [--solution-topic /bundle_adjuster/solution] [--compare-truth
//                 T.truth.yaml]
//                 [--site SITE.yaml | --site-config OVERLAY.yaml]
//   prints progress per pair and writes DIR/surface_eNN.tif, ortho_eNN.tif,
//   cloud_eNN.ply and surface_report_eNN.json / .md per epoch and
//   DIR/change_eNN.tif per later epoch (against the first epoch measured),
//   in the site's map CRS when --site (its crs) or --site-config (its
//   geodetic_origin; the config's site_file / site_config alike) gives one,
//   else in the local CRS `site` (doc/coordinates.md).
//
// The pair modes write DIR/dense_surface.tif (height, uncertainty, count, spread),
// DIR/dense_ortho.tif and, with a reference, DIR/change.tif, in the site's map
// CRS when --site (its crs) or --site-config (its geodetic_origin; else the
// --config file's site_file / site_config, as the dense_matcher node) gives
// one, else in the local CRS `site` (printed either way). A --reference
// surface in that map CRS (written by a run with the same georeference) is
// sampled back onto the new model's site grid. Exit status 0 on success, 1 on an
// error (message on stderr naming the file or key; nothing half-written).
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include <cv_bridge/cv_bridge.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <opencv2/imgcodecs.hpp>

#include "slope_monitor/AdjustmentSolution.h"
#include "slope_monitor/core/common/allocator.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/dense/change.h"
#include "slope_monitor/core/dense/dem_change.h"
#include "slope_monitor/core/dense/epoch_surface.h"
#include "slope_monitor/core/dense/surface.h"
#include "slope_monitor/core/dense/surface_series.h"
#include "slope_monitor/core/io/geotiff.h"
#include "slope_monitor/core/io/map_raster.h"
#include "slope_monitor/core/io/site_file.h"
#include "slope_monitor/core/io/yaml_map.h"
#include "slope_monitor/core/sim/truth.h"
#include "slope_monitor/ros/dense_conversions.h"
#include "slope_monitor/ros/dense_epoch_step.h"
#include "slope_monitor/ros/param_files.h"

using namespace slope_monitor;
namespace fs = std::filesystem;

namespace {

struct Args {
  std::map<std::string, std::string> kv;
  std::string Get(const std::string& k, const std::string& def = "") const {
    auto it = kv.find(k);
    return it == kv.end() ? def : it->second;
  }
  bool Has(const std::string& k) const { return kv.count(k) > 0; }
};

// The dense_matcher node's reader (config/defaults/dense_matcher.yaml): the
// same keys, defaults and checks; the node-only keys are read and not used.
// The rasters' map CRS: --site's crs, else --site-config's geodetic_origin,
// else the file's site_file / site_config (none: the local CRS `site`).
void ReadOptions(const Args& a, dense::SurfaceOptions* o, dense::SurfaceConfig* c,
                 dense::ChangeOptions* co, std::optional<SiteCrsOptions>* site_crs) {
  const std::string path = a.Get("--config");
  if (!path.empty()) {
    ros_adapters::ParamReader p(ros_adapters::LoadParamFile(path), path);
    const ros_adapters::DenseMatcherParameters d = ros_adapters::ReadDenseMatcherParameters(p);
    *o = d.surface;
    *c = d.config;
    *co = d.change;
    *site_crs = d.site_crs;
  }
  if (a.Has("--site"))
    *site_crs = io::LoadSiteFile(a.Get("--site")).crs;
  else if (a.Has("--site-config"))
    *site_crs = ros_adapters::SiteCrsOfOverlay(a.Get("--site-config"));
}

dense::OrientedImage ImageFromYaml(io::YamlMap m, const std::string& dir, const std::string& role) {
  dense::OrientedImage im;
  const std::string file = m.RequiredString("image");
  const std::string path = fs::path(file).is_absolute() ? file : (fs::path(dir) / file).string();
  im.name = role + ":" + file;
  im.image = cv::imread(path, cv::IMREAD_UNCHANGED);
  if (im.image.empty()) throw IoError(Message(path, ": cannot read the ", role, " image"));
  const std::vector<double> s = m.RequiredDoubles("sensor", 3);
  camera::Sensor sensor;
  sensor.width = static_cast<int>(s[0]);
  sensor.height = static_cast<int>(s[1]);
  sensor.pixel_size = s[2];
  const std::vector<double> in = m.RequiredDoubles("interior", camera::kNumInterior);
  std::array<double, camera::kNumInterior> interior{};
  std::copy(in.begin(), in.end(), interior.begin());
  im.camera = camera::CameraModel(
      sensor, camera::DistortionModelFromName(m.String("distortion_model", "brown")), interior);
  if (m.Has("exterior")) {
    const std::vector<double> e = m.RequiredDoubles("exterior", camera::kNumExterior);
    im.pose = camera::ExteriorOrientation::FromArray(e.data());
    im.oriented = true;
  }
  m.CheckNoUnknownKeys();
  return im;
}

cv::Mat ImageFromBag(const std::string& bag_path, const std::string& camera, double stamp) {
  rosbag::Bag bag;
  try {
    bag.open(bag_path, rosbag::bagmode::Read);
  } catch (const std::exception& e) {
    throw IoError(Message(bag_path, ": cannot open bag (", e.what(), ")"));
  }
  const std::string topic = "/" + camera + "/camera/image_raw";
  rosbag::View view(bag, rosbag::TopicQuery(topic), ros::Time(std::max(0.0, stamp - 0.5)),
                    ros::Time(stamp + 0.5));
  for (const rosbag::MessageInstance& m : view) {
    const sensor_msgs::Image::ConstPtr img = m.instantiate<sensor_msgs::Image>();
    if (img && std::abs(img->header.stamp.toSec() - stamp) < 1e-3)
      return cv_bridge::toCvCopy(img)->image;
  }
  throw IoError(Message(bag_path, ": no image on ", topic, " at stamp ", stamp));
}

dense::OrientedImage ImageFromTruth(const sim::SurveyTruth& truth, const std::string& bag,
                                    const std::string& cam, int epoch) {
  const sim::CameraTruth* c = truth.FindCamera(cam);
  if (!c) throw InvalidArgument(Message("camera '", cam, "' is not in the truth file"));
  for (const sim::ImageTruth& it : c->images)
    if (it.epoch == epoch) {
      dense::OrientedImage im;
      im.name = cam;
      im.camera = c->model;
      im.pose = it.exterior;
      im.oriented = true;
      im.image = ImageFromBag(bag, cam, it.stamp);
      return im;
    }
  throw InvalidArgument(Message("camera '", cam, "' has no image in epoch ", epoch));
}

std::string TruthSurfacePath(const sim::SurveyTruth& truth, const std::string& truth_path,
                             int epoch) {
  for (const sim::SurfaceTruth& s : truth.surfaces)
    if (s.epoch == epoch) return (fs::path(truth_path).parent_path() / s.geotiff).string();
  throw InvalidArgument(Message(truth_path, ": no true surface for epoch ", epoch));
}

// Height errors of a model against the true surface, split by where matching must fail.
void CompareWithTruth(const io::GeoRaster& model, const io::GeoRaster& true_surface,
                      const sim::SurveyTruth& truth) {
  std::vector<double> bare, hard;
  int cells = 0;
  for (int r = 0; r < model.height; ++r)
    for (int c = 0; c < model.width; ++c) {
      ++cells;
      const float z = model.At(dense::kHeight, r, c);
      if (model.IsNoData(z)) continue;
      const Eigen::Vector2d xy = model.CellCentre(r, c);
      const double zt = true_surface.Interpolate(0, xy.x(), xy.y());
      if (std::isnan(zt)) continue;
      const double e = z - zt;
      (truth.Unmatchable(Eigen::Vector3d(xy.x(), xy.y(), zt)) ? hard : bare).push_back(e);
    }
  auto report = [](const char* what, std::vector<double> e) {
    if (e.empty()) {
      std::printf("%s: no cells\n", what);
      return;
    }
    double s2 = 0, s = 0;
    for (double v : e) s2 += v * v, s += v;
    for (double& v : e) v = std::abs(v);
    std::sort(e.begin(), e.end());
    std::printf("%s: %zu cells, height error RMS %.4f m, mean %.4f m, p95 |e| %.4f m, max %.4f m\n",
                what, e.size(), std::sqrt(s2 / e.size()), s / e.size(),
                e[static_cast<size_t>(0.95 * (e.size() - 1))], e.back());
  };
  std::printf("surface vs truth (%d cells, %zu filled):\n", cells, bare.size() + hard.size());
  report("  bare ground", bare);
  report("  near scarp / trees / boulders (Unmatchable)", hard);
}

// An integer flag, or an InvalidArgument naming the flag and its value.
int IntArg(const Args& a, const std::string& flag, const std::string& default_value) {
  const std::string v = a.Get(flag, default_value);
  size_t used = 0;
  int n = 0;
  try {
    n = std::stoi(v, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (v.empty() || used != v.size() || n < 0)
    throw InvalidArgument(
        Message(flag, " '", v, "' must be a non-negative integer (an epoch number)"));
  return n;
}

// The keys of config/defaults/dense_epoch.yaml, read as the dense matcher
// node reads them (ros_adapters::ReadDenseEpochParameters); no file: the
// defaults.
// --site and --site-config win over the file's site_file and site_config.
ros_adapters::DenseEpochParameters ReadEpochConfig(const std::string& path,
                                                   const Args* site_args = nullptr) {
  XmlRpc::XmlRpcValue params =
      path.empty() ? XmlRpc::XmlRpcValue() : ros_adapters::LoadParamFile(path);
  if (site_args && site_args->Has("--site"))
    ros_adapters::SetParam(&params, "site_file", site_args->Get("--site"));
  if (site_args && site_args->Has("--site-config"))
    ros_adapters::SetParam(&params, "site_config", site_args->Get("--site-config"));
  ros_adapters::ParamReader reader(params, path);
  return ros_adapters::ReadDenseEpochParameters(reader);
}

// Every adjusted epoch of the bag (see the file header).
int RunBagEpochs(const Args& a) {
  const ros_adapters::DenseEpochParameters cfg = ReadEpochConfig(a.Get("--config"), &a);
  const std::string bag_path = a.Get("--bag"),
                    topic = a.Get("--solution-topic", "/bundle_adjuster/solution");
  const std::string out_dir = a.Get("--out-dir", ".");
  const int only_epoch = a.Has("--epoch") ? IntArg(a, "--epoch", "") : -1;
  rosbag::Bag bag;
  try {
    bag.open(bag_path, rosbag::bagmode::Read);
  } catch (const std::exception& e) {
    throw IoError(Message(bag_path, ": cannot open bag (", e.what(), ")"));
  }
  std::vector<slope_monitor::AdjustmentSolution> solutions;
  for (const rosbag::MessageInstance& m : rosbag::View(bag, rosbag::TopicQuery(topic))) {
    const auto s = m.instantiate<slope_monitor::AdjustmentSolution>();
    if (s && s->usable && (only_epoch < 0 || static_cast<int>(s->epoch) == only_epoch))
      solutions.push_back(*s);
  }
  if (solutions.empty())
    throw InvalidArgument(
        Message(bag_path, ": no usable adjustment on ", topic,
                (only_epoch >= 0 ? Message(" for epoch ", only_epoch) : std::string()),
                " (record a replay with record.launch, or run process_bag --output-bag)"));
  fs::create_directories(out_dir);
  // The node's epoch series (reference, DoD, its files in --out-dir: dense/surface_series.h).
  ros_adapters::DenseEpochParameters series_cfg = cfg;
  series_cfg.report_dir = out_dir;
  dense::SurfaceSeries series(ros_adapters::SeriesOptions(series_cfg));
  for (const slope_monitor::AdjustmentSolution& sol : solutions) {
    dense::EpochSurfaceInput in;
    in.epoch = static_cast<int>(sol.epoch);
    in.stereo_pairs = cfg.stereo_pairs;
    in.adjusted_points = ros_adapters::AdjustedPoints(sol);
    for (const slope_monitor::CameraEstimate& e : sol.cameras) {
      const double t = e.image_header.stamp.toSec();
      sensor_msgs::Image::ConstPtr image;
      sensor_msgs::CameraInfo::ConstPtr info;
      // By header stamp, not bag time: a recorded bag carries the receive time.
      for (const rosbag::MessageInstance& m :
           rosbag::View(bag, rosbag::TopicQuery({"/" + e.camera_name + "/camera/image_raw",
                                                 "/" + e.camera_name + "/camera/camera_info"}))) {
        if (image && info) break;
        if (auto i = m.instantiate<sensor_msgs::Image>())
          if (std::abs(i->header.stamp.toSec() - t) < 1e-3) image = i;
        if (auto c = m.instantiate<sensor_msgs::CameraInfo>()) info = c;
      }
      if (!image || !info) {
        std::printf("epoch %u: no image/camera_info of '%s' at %.3f in the bag; skipped\n",
                    sol.epoch, e.camera_name.c_str(), t);
        continue;
      }
      const bool uav = std::find(cfg.uav_cameras.begin(), cfg.uav_cameras.end(), e.camera_name) !=
                       cfg.uav_cameras.end();
      in.images.push_back(ros_adapters::EpochImageFromEstimate(
          e, *image, *info, cfg.pixel_size,
          uav ? dense::ImageKind::kUav : dense::ImageKind::kFixed));
    }
    std::printf("epoch %d: %zu oriented images, %zu adjusted points\n", in.epoch, in.images.size(),
                in.adjusted_points.size());
    std::fflush(stdout);
    const dense::SeriesEpoch r = series.Measure(in, [](const std::string& step) {
      std::printf("  %s\n", step.c_str());
      std::fflush(stdout);
    });
    for (const std::string& e : r.errors) std::fprintf(stderr, "dense_surface: %s\n", e.c_str());
    if (!r.surface) continue;
    std::printf("%s\n", r.surface->summary.BriefReport().c_str());
    if (a.Has("--compare-truth")) {
      const std::string truth_path = a.Get("--compare-truth");
      const sim::SurveyTruth truth = sim::SurveyTruth::Load(truth_path);
      CompareWithTruth(r.surface->dem,
                       io::ReadGeoTiff(TruthSurfacePath(truth, truth_path, in.epoch)), truth);
    }
    if (r.change_summary)
      std::printf("epoch %d change: %s\n", in.epoch, r.change_summary->BriefReport().c_str());
  }
  return series.reference() ? 0 : 1;
}

// The name of the truth's `index`-th camera of kind fixed (the default
// --left-camera 0 and --right-camera 1): no camera name is assumed.
std::string FixedCameraOfTruth(const sim::SurveyTruth& truth, size_t index) {
  std::vector<std::string> fixed;
  for (const sim::CameraTruth& c : truth.cameras)
    if (c.kind == "fixed") fixed.push_back(c.name);
  if (index >= fixed.size())
    throw InvalidArgument(
        Message("the truth has ", fixed.size(),
                " camera(s) of kind fixed: give --left-camera and --right-camera"));
  return fixed[index];
}

int Run(const Args& a) {
  if (a.Has("--bag") && !a.Has("--truth")) return RunBagEpochs(a);
  dense::SurfaceOptions options;
  options.correlation.final_grid_spacing = 2;
  options.min_points_per_cell = 2;
  dense::SurfaceConfig config;
  config.min_depth = 5.0;
  config.max_depth = 500.0;
  dense::ChangeOptions change_options;
  std::optional<SiteCrsOptions> site_crs;
  ReadOptions(a, &options, &config, &change_options, &site_crs);
  const std::unique_ptr<SiteCrs> site = site_crs ? std::make_unique<SiteCrs>(*site_crs) : nullptr;
  if (site)
    std::printf("rasters in %s (the site's map CRS)\n", site->MapCrs().c_str());
  else
    std::printf(
        "rasters in the local CRS 'site' (no EPSG code: give --site or --site-config to "
        "georeference them)\n");
  const std::string out_dir = a.Get("--out-dir", ".");
  fs::create_directories(out_dir);

  dense::OrientedImage left, right;
  std::string left_camera, right_camera;  // --truth: their names
  std::unique_ptr<sim::SurveyTruth> truth;
  int epoch = 0;
  if (a.Has("--truth")) {
    epoch = IntArg(a, "--epoch", "0");  // before loading anything
    truth = std::make_unique<sim::SurveyTruth>(sim::SurveyTruth::Load(a.Get("--truth")));
    left_camera = a.Has("--left-camera") ? a.Get("--left-camera") : FixedCameraOfTruth(*truth, 0);
    right_camera =
        a.Has("--right-camera") ? a.Get("--right-camera") : FixedCameraOfTruth(*truth, 1);
    left = ImageFromTruth(*truth, a.Get("--bag"), left_camera, epoch);
    right = ImageFromTruth(*truth, a.Get("--bag"), right_camera, epoch);
    if (config.region.isZero())
      config.region =
          Eigen::Vector4d(truth->extent[0], truth->extent[1], truth->extent[2], truth->extent[3]);
  } else if (a.Has("--pair")) {
    const std::string pair_path = a.Get("--pair");
    io::YamlMap root = io::YamlMap::Load(pair_path);
    const std::string dir = fs::path(pair_path).parent_path().string();
    left = ImageFromYaml(root.Map("left"), dir, "left");
    right = ImageFromYaml(root.Map("right"), dir, "right");
    root.CheckNoUnknownKeys();
  } else {
    throw InvalidArgument(
        "give --pair pair.yaml or --truth demo.truth.yaml --bag demo.bag (see the file header)");
  }

  dense::SurfaceSummary summary;
  // DIR/dense_surface.tif and DIR/dense_ortho.tif, written only after the measurement succeeded.
  const dense::SurfaceResult s = dense::MeasureSurfaceToFiles(
      left, right, options, config, (fs::path(out_dir) / "dense").string(), &summary, site.get());
  std::printf("%s\n", summary.BriefReport().c_str());

  io::GeoRaster true_now;
  if (truth) {
    true_now = io::ReadGeoTiff(TruthSurfacePath(*truth, a.Get("--truth"), epoch));
    CompareWithTruth(s.model, true_now, *truth);
  }

  std::unique_ptr<io::GeoRaster> reference;
  if (truth && a.Has("--reference-epoch")) {
    const int ref_epoch = IntArg(a, "--reference-epoch", "");
    const dense::OrientedImage l0 = ImageFromTruth(*truth, a.Get("--bag"), left_camera, ref_epoch);
    const dense::OrientedImage r0 = ImageFromTruth(*truth, a.Get("--bag"), right_camera, ref_epoch);
    reference =
        std::make_unique<io::GeoRaster>(dense::MeasureSurface(l0, r0, options, config).model);
  } else if (a.Has("--reference")) {
    // Written in the map CRS: sampled back onto the model's site grid (cells
    // it does not cover: nodata); in `site` (no georeference): as it is, its
    // grid the model's.
    const std::string ref_path = a.Get("--reference");
    try {
      const io::GeoRaster ref = io::ReadGeoTiff(ref_path);
      reference =
          std::make_unique<io::GeoRaster>(site ? io::SiteRasterFromMap(ref, site.get(), s.model)
                                               : io::SiteRasterFromMap(ref, nullptr));
    } catch (const InvalidArgument& e) {
      throw InvalidArgument(Message("--reference ", ref_path, ": ", e.what()));
    }
  }
  if (reference) {
    const dense::ChangeResult c = dense::SurfaceChange(*reference, s.model, change_options);
    std::printf("%s\n", c.summary.BriefReport().c_str());
    io::WriteGeoTiff((fs::path(out_dir) / "change.tif").string(),
                     io::MapRasterFromSite(c.change, site.get()));
    if (truth && a.Has("--reference-epoch")) {
      const io::GeoRaster true_ref = io::ReadGeoTiff(
          TruthSurfacePath(*truth, a.Get("--truth"), IntArg(a, "--reference-epoch", "")));
      // True cut and fill over the whole model grid and over the significant cells.
      double gain = 0, loss = 0, gain_sig = 0, loss_sig = 0;
      const double area = c.change.cell_size * c.change.cell_size;
      for (int r = 0; r < c.change.height; ++r)
        for (int k = 0; k < c.change.width; ++k) {
          const Eigen::Vector2d xy = c.change.CellCentre(r, k);
          const double dz =
              true_now.Interpolate(0, xy.x(), xy.y()) - true_ref.Interpolate(0, xy.x(), xy.y());
          if (std::isnan(dz)) continue;
          (dz > 0 ? gain : loss) += std::abs(dz) * area;
          const float sig = c.change.At(dense::kSignificant, r, k);
          if (!c.change.IsNoData(sig) && sig != 0.0f)
            (dz > 0 ? gain_sig : loss_sig) += std::abs(dz) * area;
        }
      std::printf(
          "true change over the grid: gain %.2f m3, loss %.2f m3, net %.2f m3; over the "
          "significant cells: "
          "gain %.2f m3, loss %.2f m3\n",
          gain, loss, gain - loss, gain_sig, loss_sig);
      std::printf(
          "ratio volume_gain measured/true = %.3f\nratio volume_loss measured/true = %.3f\n",
          gain > 0 ? c.summary.volume_gain / gain : 0.0,
          loss > 0 ? c.summary.volume_loss / loss : 0.0);
    }
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  slope_monitor::KeepFreedMemoryForReuse();  // core/common/allocator.h
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    if (k == "-h" || k == "--help") {
      std::printf(
          "usage: dense_surface --bag B.bag --out-dir DIR [--config "
          "config/defaults/dense_epoch.yaml] "
          "[--epoch K] [--solution-topic T] [--compare-truth T.truth.yaml]\n"
          "                     [--site SITE.yaml | --site-config OVERLAY.yaml]  (the GeoTIFFs' "
          "map CRS)\n"
          "       dense_surface --pair pair.yaml --out-dir DIR [--config FILE] [--reference "
          "surface.tif]\n"
          "                     [--site SITE.yaml | --site-config OVERLAY.yaml]  (the rasters' map "
          "CRS; also with --truth)\n"
          "       dense_surface --truth T.truth.yaml --bag T.bag --left-camera C1 --right-camera "
          "C2 "
          "--epoch K [--reference-epoch K0] --out-dir DIR [--config FILE]\n");
      return 0;
    }
    if (k.rfind("--", 0) != 0 || i + 1 >= argc) {
      std::fprintf(stderr, "dense_surface: bad argument '%s' (see --help)\n", k.c_str());
      return 1;
    }
    a.kv[k] = argv[++i];
  }
  try {
    return Run(a);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dense_surface: %s\n", e.what());
    return 1;
  }
}
