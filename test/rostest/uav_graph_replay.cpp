// Plays the uav_graph_replay survey (two fixed cameras and a UAV strip)
// through the whole graph and checks the bundle adjuster's outputs against
// the simulator's truth (uav_replay_checks.h; tolerances in
// uav_graph_replay.test.in).
#include "uav_replay_checks.h"

TEST(UavGraphReplay, UavPhotosContribute) { slope_monitor::uav_replay::CheckUavReplay(); }

int main(int argc, char** argv) { return RunUavReplayTest(argc, argv, "uav_graph_replay_test"); }
