#include "slope_monitor/ros/radio_conversions.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

#include "slope_monitor/ros/deformation_conversions.h"

namespace slope_monitor {
namespace ros_adapters {

radio::SampleBlock FromMsg(const slope_monitor::RadioSampleBlock& m) {
  radio::SampleBlock b;
  b.receiver_id = m.receiver_id;
  b.frame_id = m.header.frame_id;
  b.stamp = m.header.stamp.toSec();
  b.sequence = m.sequence;
  b.sample_rate = m.sample_rate;
  b.center_frequency = m.center_frequency;
  b.full_scale = m.full_scale;
  b.i = m.i;
  b.q = m.q;
  return b;
}

RadioOutputs MakeRadioOutputs(const radio::RadioEpochSummary& s, const std_msgs::Header& header,
                              uint32_t epoch) {
  RadioOutputs r;
  r.observations.header = header;
  for (const auto& o : s.observations) {
    slope_monitor::RadioPhaseObservation m;
    m.receiver_id = o.receiver_id;
    m.transmitter_id = o.transmitter_id;
    m.frequency = o.frequency;
    m.phase = o.phase;
    m.phase_variance = o.phase_variance;
    m.amplitude = o.amplitude;
    m.snr = o.snr;
    r.observations.observations.push_back(m);
  }
  if (!s.IsSolutionUsable()) return r;
  slope_monitor::PointDisplacementArray out;
  out.header = header;
  out.epoch = epoch;
  for (const auto& t : s.transmitters) {
    if (!t.initialized) continue;
    // The reference block itself: its displacement is zero by definition with
    // a singular covariance; it is the datum, not a measurement of motion.
    if (t.displacement_covariance.diagonal().minCoeff() <= 0.0 ||
        Eigen::LLT<Eigen::Matrix3d>(t.displacement_covariance).info() != Eigen::Success)
      continue;
    slope_monitor::PointDisplacement d =
        MakePointDisplacement(t.id, slope_monitor::PointDisplacement::SOURCE_RADIO,
                              "radio_phase_solver", t.reference_stamp, header.stamp,
                              t.reference_position, t.displacement, t.displacement_covariance);
    const double n = t.displacement.norm();
    if (n > 0.0) {
      const Eigen::Vector3d u = t.displacement / n;
      const double sigma = std::sqrt(std::max(0.0, u.dot(t.displacement_covariance * u)));
      d.significance = sigma > 0.0 ? n / sigma : 0.0;
    }
    out.displacements.push_back(d);
  }
  r.displacements = out;
  return r;
}

}  // namespace ros_adapters
}  // namespace slope_monitor
