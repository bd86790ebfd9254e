// rostest: the drape_simulator node answers simulate_drape, rejects malformed requests with an error
// response, and keeps running afterwards.
#include <gtest/gtest.h>
#include <ros/ros.h>

#include <cmath>
#include <limits>

#include "textile_handling/SimulateDrape.h"

namespace {

std::string serviceName() {
  std::string name = "/drape_simulator/simulate_drape";
  ros::param::param<std::string>("~service", name, name);
  return name;
}

bool call(textile_handling::SimulateDrape& srv) {
  ros::ServiceClient client = ros::NodeHandle().serviceClient<textile_handling::SimulateDrape>(serviceName());
  return client.call(srv);
}

}  // namespace

TEST(DrapeSimulatorNode, SimulatesSquareHeldAtCorner) {
  ASSERT_TRUE(ros::service::waitForService(serviceName(), ros::Duration(30)));
  textile_handling::SimulateDrape srv;
  srv.request.textile = "square";
  srv.request.hold_point = "corner_ul";
  ASSERT_TRUE(call(srv));
  EXPECT_TRUE(srv.response.success) << srv.response.message;
  EXPECT_FALSE(srv.response.summary.diverged);
  EXPECT_TRUE(srv.response.summary.rest_reached) << srv.response.message;
  EXPECT_EQ(srv.response.summary.particles, 11 * 11);
  double expected = 0, tol = 0;
  ros::param::param("~expected_depth_m", expected, 0.42);
  ros::param::param("~depth_tolerance_m", tol, 0.04);
  EXPECT_NEAR(srv.response.summary.hanging_depth_m, expected, tol);
}

TEST(DrapeSimulatorNode, RejectsMalformedRequestsAndStaysUp) {
  ASSERT_TRUE(ros::service::waitForService(serviceName(), ros::Duration(30)));
  textile_handling::SimulateDrape unknown;
  unknown.request.textile = "sock";
  unknown.request.hold_point = "corner_ul";
  ASSERT_TRUE(call(unknown));
  EXPECT_FALSE(unknown.response.success);
  EXPECT_NE(unknown.response.message.find("sock"), std::string::npos) << unknown.response.message;

  textile_handling::SimulateDrape nan_spacing;
  nan_spacing.request.textile = "square";
  nan_spacing.request.hold_point = "corner_ul";
  nan_spacing.request.spacing_m = std::numeric_limits<double>::quiet_NaN();
  ASSERT_TRUE(call(nan_spacing));
  EXPECT_FALSE(nan_spacing.response.success);
  EXPECT_NE(nan_spacing.response.message.find("spacing"), std::string::npos);

  textile_handling::SimulateDrape bad_point;
  bad_point.request.textile = "square";
  bad_point.request.hold_point = "no_such_point";
  ASSERT_TRUE(call(bad_point));
  EXPECT_FALSE(bad_point.response.success);

  textile_handling::SimulateDrape bad_xy;
  bad_xy.request.textile = "square";
  bad_xy.request.hold_xy = {0.1};
  ASSERT_TRUE(call(bad_xy));
  EXPECT_FALSE(bad_xy.response.success);

  textile_handling::SimulateDrape bad_integrator;
  bad_integrator.request.textile = "square";
  bad_integrator.request.hold_point = "corner_ul";
  bad_integrator.request.integrator = "leapfrog";
  ASSERT_TRUE(call(bad_integrator));
  EXPECT_FALSE(bad_integrator.response.success);

  // Still up and serving.
  EXPECT_TRUE(ros::service::waitForService(serviceName(), ros::Duration(5)));
  textile_handling::SimulateDrape ok;
  ok.request.textile = "square";
  ok.request.hold_xy = {0.15, 0.15};
  ASSERT_TRUE(call(ok));
  EXPECT_TRUE(ok.response.success) << ok.response.message;
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_drape_simulator_node");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
