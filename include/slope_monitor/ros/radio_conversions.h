// Radio messages <-> core radio types, shared by the radio_phase_solver
// nodelet and the process_bag tool.
#pragma once

#include <optional>

#include <std_msgs/Header.h>

#include "slope_monitor/PointDisplacementArray.h"
#include "slope_monitor/RadioPhaseObservationArray.h"
#include "slope_monitor/RadioSampleBlock.h"
#include "slope_monitor/core/radio/phase_solver.h"

namespace slope_monitor {
namespace ros_adapters {

radio::SampleBlock FromMsg(const slope_monitor::RadioSampleBlock& m);

struct RadioOutputs {
  slope_monitor::RadioPhaseObservationArray observations;
  // Only for a usable solution: every initialised transmitter but the datum.
  std::optional<slope_monitor::PointDisplacementArray> displacements;
};
// `header`: stamp of the epoch, frame of the solver; `epoch`: the solver's
// epoch count (PointDisplacementArray.epoch).
RadioOutputs MakeRadioOutputs(const radio::RadioEpochSummary& s, const std_msgs::Header& header,
                              uint32_t epoch);

}  // namespace ros_adapters
}  // namespace slope_monitor
