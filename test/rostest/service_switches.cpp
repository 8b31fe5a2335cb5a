// Test node of service_switches.test: with enable_run_adjustment,
// enable_set_reference_epoch and enable_export_report false the services are
// not advertised; with the defaults they are (issue 22). resect_camera changes
// no state and is always advertised: an empty request is answered, naming why.
#include <string>

#include <ros/master.h>
#include <ros/service.h>

#include "slope_monitor/ResectCamera.h"
#include "test_node.h"

namespace slope_monitor {
namespace {

TEST(ServiceSwitches, DefaultsAdvertiseSwitchedOffDoNot) {
  // The switched-on services show that the nodes are up.
  for (const char* s : {"/adjuster_on/run_adjustment", "/adjuster_on/set_reference_epoch",
                        "/estimator_on/export_report", "/estimator_on/set_reference_epoch"})
    ASSERT_TRUE(ros::service::waitForService(s, ros::Duration(30.0))) << s << " not advertised";
  // Both "off" nodes started alongside; their other outputs show that they are up.
  ASSERT_TRUE(rostest_node::WaitFor(
      [] {
        ros::master::V_TopicInfo topics;
        ros::master::getTopics(topics);
        int up = 0;
        for (const auto& t : topics)
          up += t.name == "/adjuster_off/solution" || t.name == "/estimator_off/deformation";
        return up == 2;
      },
      30.0))
      << "the switched-off nodes did not come up";
  for (const char* s : {"/adjuster_off/run_adjustment", "/adjuster_off/set_reference_epoch",
                        "/estimator_off/export_report", "/estimator_off/set_reference_epoch"})
    EXPECT_FALSE(ros::service::exists(s, false)) << s << " is advertised although switched off";
}

TEST(ServiceSwitches, ResectCameraIsAlwaysAdvertisedAndNamesABadRequest) {
  const std::string s = "/adjuster_off/resect_camera";
  ASSERT_TRUE(ros::service::waitForService(s, ros::Duration(30.0))) << s << " not advertised";
  slope_monitor::ResectCamera srv;
  srv.request.camera_info.width = 4000;
  srv.request.camera_info.height = 3000;
  srv.request.camera_info.K = {4000, 0, 1999.5, 0, 4000, 1499.5, 0, 0, 1};
  ASSERT_TRUE(ros::service::call(s, srv));
  EXPECT_FALSE(srv.response.success);
  EXPECT_NE(srv.response.message.find("4"), std::string::npos) << srv.response.message;
}

}  // namespace
}  // namespace slope_monitor

int main(int argc, char** argv) {
  return slope_monitor::rostest_node::RunTests(argc, argv, "service_switches_test");
}
