// Plays the uav_block_replay survey (the UAV alone: two parallel strips
// 60 m above the slope, tie points from hex_matcher, the camera
// self-calibrated in every flight) through the whole graph and checks the
// bundle adjuster's outputs against the simulator's truth, the
// self-calibrated c, principal point and k1 included (uav_replay_checks.h;
// tolerances in uav_block_replay.test.in).
#include "uav_replay_checks.h"

TEST(UavBlockReplay, UavAloneSelfCalibrated) { slope_monitor::uav_replay::CheckUavReplay(); }

int main(int argc, char** argv) { return RunUavReplayTest(argc, argv, "uav_block_replay_test"); }
