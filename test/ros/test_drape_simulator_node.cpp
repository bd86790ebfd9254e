// rostest: the drape_simulator node answers simulate_drape; register_textile -> build on the worker ->
// list_textiles -> resimulate -> publish_rest_shape on a temporary database, with progress and
// database_changed topics; malformed requests get error responses and the node keeps running.
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <visualization_msgs/MarkerArray.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <mutex>

#include "textile_handling/BuildProgress.h"
#include "textile_handling/DatabaseChanged.h"
#include "textile_handling/ListTextiles.h"
#include "textile_handling/PublishRestShape.h"
#include "textile_handling/RegisterTextile.h"
#include "textile_handling/Resimulate.h"
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

namespace {

template <typename Srv>
bool callService(const std::string& name, Srv& srv) {
  const std::string full = "/drape_simulator/" + name;
  if (!ros::service::waitForService(full, ros::Duration(30))) return false;
  return ros::service::call(full, srv);
}

textile_handling::RegisterTextile napkinRequest(const std::string& name) {
  textile_handling::RegisterTextile srv;
  srv.request.name = name;
  srv.request.outline_x = {0, 0.3, 0.3, 0};
  srv.request.outline_y = {0, 0, 0.3, 0.3};
  textile_handling::NamedPoint2D c;
  c.name = "corner_a";
  c.kind = "corner";
  srv.request.named_points.push_back(c);
  textile_handling::NamedPoint2D g;
  g.name = "middle";
  g.kind = "grasp";
  g.x = g.y = 0.15;
  srv.request.named_points.push_back(g);
  srv.request.material = "cotton";
  return srv;
}

// Polls list_textiles until `name` has `done` finished simulations and nothing pending in an active
// generation >= `generation` with no resimulation in progress, or times out.
bool waitForBuild(const std::string& name, int done, double timeout_s, textile_handling::TextileInfo* info,
                  std::int64_t generation = 0) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
  while (ros::WallTime::now() < end) {
    textile_handling::ListTextiles list;
    if (callService("list_textiles", list))
      for (const auto& t : list.response.textiles)
        if (t.name == name && t.simulations_done == done && t.simulations_pending == 0 && t.generation >= generation &&
            t.staged_simulations == 0) {
          *info = t;
          return true;
        }
    ros::WallDuration(0.5).sleep();
  }
  return false;
}

struct TopicLog {
  std::mutex mu;
  std::vector<textile_handling::BuildProgress> progress;
  std::vector<textile_handling::DatabaseChanged> changed;
  std::vector<visualization_msgs::MarkerArray> markers;
};

}  // namespace

TEST(DrapeSimulatorNode, RegisterResimulateListOnATemporaryDatabase) {
  TopicLog log;
  ros::NodeHandle nh;
  ros::Subscriber ps = nh.subscribe<textile_handling::BuildProgress>(
      "/drape_simulator/build_progress", 100, [&](const textile_handling::BuildProgress::ConstPtr& m) {
        std::lock_guard<std::mutex> l(log.mu);
        log.progress.push_back(*m);
      });
  ros::Subscriber cs = nh.subscribe<textile_handling::DatabaseChanged>(
      "/drape_simulator/database_changed", 10, [&](const textile_handling::DatabaseChanged::ConstPtr& m) {
        std::lock_guard<std::mutex> l(log.mu);
        log.changed.push_back(*m);
      });
  ros::Subscriber ms = nh.subscribe<visualization_msgs::MarkerArray>(
      "/drape_simulator/rest_shape_markers", 10, [&](const visualization_msgs::MarkerArray::ConstPtr& m) {
        std::lock_guard<std::mutex> l(log.mu);
        log.markers.push_back(*m);
      });
  ros::AsyncSpinner spinner(1);
  spinner.start();
  ros::WallDuration(1.0).sleep();  // let the subscriptions connect

  auto reg = napkinRequest("napkin");
  const ros::WallTime t0 = ros::WallTime::now();
  ASSERT_TRUE(callService("register_textile", reg));
  ASSERT_TRUE(reg.response.success) << reg.response.message;
  EXPECT_LT((ros::WallTime::now() - t0).toSec(), 10.0);  // returns at once, the build runs behind
  EXPECT_GT(reg.response.textile_id, 0);
  EXPECT_EQ(reg.response.queued_simulations, 9);  // 0.3 m square, 0.15 m lattice

  textile_handling::TextileInfo info;
  ASSERT_TRUE(waitForBuild("napkin", 9, 90.0, &info));
  EXPECT_EQ(info.id, reg.response.textile_id);
  EXPECT_EQ(info.material, "cotton");
  EXPECT_EQ(info.named_points.size(), 2u);
  EXPECT_EQ(info.symmetry, "xy");
  EXPECT_EQ(info.views, 9 * 4);
  EXPECT_EQ(info.outline_x.size(), 4u);

  textile_handling::PublishRestShape shape;
  shape.request.textile_id = info.id;
  ASSERT_TRUE(callService("publish_rest_shape", shape));
  EXPECT_TRUE(shape.response.success) << shape.response.message;
  ros::WallDuration(1.0).sleep();
  {
    // 7 x 7 particles at d = 5 cm: 6 x 6 cells, 2 triangles each.
    std::lock_guard<std::mutex> l(log.mu);
    ASSERT_FALSE(log.markers.empty());
    ASSERT_EQ(log.markers.back().markers.size(), 2u);
    EXPECT_EQ(log.markers.back().markers[1].points.size(), 3u * 72u);
  }

  textile_handling::Resimulate resim;
  resim.request.textile_id = info.id;
  resim.request.spacing_m = 0.03;
  ASSERT_TRUE(callService("resimulate", resim));
  ASSERT_TRUE(resim.response.success) << resim.response.message;
  EXPECT_EQ(resim.response.queued_simulations, 9);
  // The old entries stay active (9 done) while the new ones are built beside them; the promotion
  // makes the next generation active.
  const std::int64_t old_generation = info.generation;
  ASSERT_TRUE(waitForBuild("napkin", 9, 90.0, &info, old_generation + 1));
  EXPECT_EQ(info.generation, old_generation + 1);
  ASSERT_TRUE(callService("publish_rest_shape", shape));
  EXPECT_TRUE(shape.response.success) << shape.response.message;
  ros::WallDuration(1.0).sleep();

  std::lock_guard<std::mutex> l(log.mu);
  bool saw_done = false, saw_running = false;
  for (const auto& p : log.progress) {
    saw_done = saw_done || (p.state == "done" && p.textile_name == "napkin" && p.done == p.total);
    saw_running = saw_running || p.state == "running";
  }
  EXPECT_TRUE(saw_running);
  EXPECT_TRUE(saw_done);
  ASSERT_FALSE(log.changed.empty());
  EXPECT_GE(log.changed.back().simulations_done, 9);
  ASSERT_FALSE(log.markers.empty());
  const auto& arr = log.markers.back();
  ASSERT_EQ(arr.markers.size(), 2u);  // DELETEALL + the mesh
  EXPECT_EQ(arr.markers[1].type, visualization_msgs::Marker::TRIANGLE_LIST);
  EXPECT_EQ(arr.markers[1].points.size() % 3, 0u);
  // Rebuilt at d = 3 cm: 11 x 11 particles, 10 x 10 cells, 2 triangles each.
  EXPECT_EQ(arr.markers[1].points.size(), 3u * 200u);
}

TEST(DrapeSimulatorNode, MalformedRegistrationsAreRejectedAndTheDatabaseIsUntouched) {
  textile_handling::ListTextiles before;
  ASSERT_TRUE(callService("list_textiles", before));

  auto bowtie = napkinRequest("bowtie");
  bowtie.request.outline_x = {0, 0.3, 0.3, 0};
  bowtie.request.outline_y = {0, 0.3, 0, 0.3};
  bowtie.request.named_points.clear();
  ASSERT_TRUE(callService("register_textile", bowtie));
  EXPECT_FALSE(bowtie.response.success);
  EXPECT_NE(bowtie.response.message.find("outline"), std::string::npos) << bowtie.response.message;

  auto ragged = napkinRequest("ragged");
  ragged.request.outline_y.pop_back();
  ASSERT_TRUE(callService("register_textile", ragged));
  EXPECT_FALSE(ragged.response.success);

  auto nan_spacing = napkinRequest("nan_spacing");
  nan_spacing.request.hold_point_spacing_m = std::numeric_limits<double>::quiet_NaN();
  ASSERT_TRUE(callService("register_textile", nan_spacing));
  EXPECT_FALSE(nan_spacing.response.success);

  auto bad_material = napkinRequest("bad_material");
  bad_material.request.material_yaml = "name: x\nareal_density: .nan\n";
  ASSERT_TRUE(callService("register_textile", bad_material));
  EXPECT_FALSE(bad_material.response.success);

  textile_handling::Resimulate unknown;
  unknown.request.textile_id = 987654;
  ASSERT_TRUE(callService("resimulate", unknown));
  EXPECT_FALSE(unknown.response.success);
  EXPECT_NE(unknown.response.message.find("987654"), std::string::npos) << unknown.response.message;

  textile_handling::PublishRestShape no_shape;
  no_shape.request.textile_id = 987654;
  ASSERT_TRUE(callService("publish_rest_shape", no_shape));
  EXPECT_FALSE(no_shape.response.success);

  textile_handling::ListTextiles after;
  ASSERT_TRUE(callService("list_textiles", after));
  EXPECT_EQ(after.response.textiles.size(), before.response.textiles.size());
}

TEST(DrapeSimulatorNode, HostileRequestsGetClearErrorsAndTheNodeStaysUp) {
  textile_handling::ListTextiles before;
  ASSERT_TRUE(callService("list_textiles", before));
  // 100,000 outline vertices (a circle): refused by the size limit before any validation work.
  auto huge = napkinRequest("huge_outline");
  huge.request.named_points.clear();
  huge.request.outline_x.clear();
  huge.request.outline_y.clear();
  for (int k = 0; k < 100000; ++k) {
    huge.request.outline_x.push_back(0.3 + 0.3 * std::cos(2 * M_PI * k / 100000));
    huge.request.outline_y.push_back(0.3 + 0.3 * std::sin(2 * M_PI * k / 100000));
  }
  ASSERT_TRUE(callService("register_textile", huge));
  EXPECT_FALSE(huge.response.success);
  EXPECT_NE(huge.response.message.find("limit"), std::string::npos) << huge.response.message;
  // A named point whose name is not a name.
  auto injection = napkinRequest("injection");
  injection.request.named_points[0].name = "x'); DROP TABLE grasp_points;--";
  ASSERT_TRUE(callService("register_textile", injection));
  EXPECT_FALSE(injection.response.success);
  EXPECT_NE(injection.response.message.find("name"), std::string::npos) << injection.response.message;
  // A simulation that would need far more memory than the machine has is refused, not attempted.
  textile_handling::SimulateDrape fine;
  fine.request.textile = "towel";
  fine.request.hold_point = "corner_ul";
  fine.request.spacing_m = 2e-4;
  ASSERT_TRUE(callService("simulate_drape", fine));
  EXPECT_FALSE(fine.response.success);
  EXPECT_NE(fine.response.message.find("memory"), std::string::npos) << fine.response.message;
  // The node is alive and the stored textiles are unchanged.
  textile_handling::ListTextiles after;
  ASSERT_TRUE(callService("list_textiles", after));
  ASSERT_EQ(after.response.textiles.size(), before.response.textiles.size());
  for (std::size_t k = 0; k < after.response.textiles.size(); ++k)
    EXPECT_EQ(after.response.textiles[k].name, before.response.textiles[k].name);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_drape_simulator_node");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
