#include "slope_monitor/ros/offline_dense.h"

#include <algorithm>
#include <chrono>
#include <ctime>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/ros/parameters.h"

namespace slope_monitor {
namespace ros_adapters {

constexpr char OfflineDense::kCloudTopic[];
constexpr char OfflineDense::kAreasTopic[];
constexpr char OfflineDense::kLegendTopic[];

OfflineDense::OfflineDense(const XmlRpc::XmlRpcValue& params,
                           std::function<void(const DenseEpochOutput&)> write,
                           std::function<void(const std::string&)> log)
    : write_(std::move(write)), log_(std::move(log)) {
  ParamReader reader(params, "/dense/dense_matcher");
  const DenseEpochParameters p = ReadDenseEpochParameters(reader);
  cameras_ = p.cameras;
  step_ = std::make_unique<DenseEpochStep>(p);
}

bool OfflineDense::Camera(const std::string& camera) const {
  return std::find(cameras_.begin(), cameras_.end(), camera) != cameras_.end() &&
         step_->Uses(camera);
}

void OfflineDense::OnImage(const std::string& camera, const sensor_msgs::Image& image, double now) {
  if (!Camera(camera)) return;
  const std::vector<dense::PhotoEpoch> done = step_->OnImage(camera, image, now);
  Log(step_->TakeLog());
  Measure(done);
}

void OfflineDense::OnCameraInfo(const std::string& camera, const sensor_msgs::CameraInfo& info) {
  if (!Camera(camera)) return;
  try {
    step_->OnCameraInfo(camera, info);
  } catch (const Error& e) {
    log_(std::string("dense_matcher: ") + e.what());
  }
}

void OfflineDense::OnSolution(const slope_monitor::AdjustmentSolution& solution, double now) {
  const std::vector<dense::PhotoEpoch> done = step_->OnSolution(solution, now);
  Log(step_->TakeLog());
  Measure(done);
}

void OfflineDense::Finish() {
  const std::vector<dense::PhotoEpoch> done = step_->Finish();
  Log(step_->TakeLog());
  Measure(done);
}

void OfflineDense::Measure(const std::vector<dense::PhotoEpoch>& epochs) {
  for (const dense::PhotoEpoch& e : epochs) {
    const auto start = std::chrono::steady_clock::now();
    const std::clock_t cpu_start = std::clock();
    const DenseEpochOutput out = step_->Measure(e);
    seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    cpu_seconds_ += static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC;
    Log(out.log);
    if (out.cloud) ++epochs_;
    write_(out);
  }
}

void OfflineDense::Log(const std::vector<LogLine>& lines) {
  for (const LogLine& l : lines)
    if (l.level >= LogLine::kInfo) log_("dense_matcher: " + l.text);
}

}  // namespace ros_adapters
}  // namespace slope_monitor
