#!/usr/bin/python3
"""Prints the textile_recognizer's results (textile, hold point, grasp poses) and exits after N of them.

Usage (inside a ROS graph): print_recognition.py [_count:=N] [_topic:=/textile_recognizer/result]
Exit status 0 when N successful results arrived, 1 on timeout (_timeout:=S wall seconds).
"""
import sys
import time

import rospy
from textile_handling.msg import RecognitionResult


def main():
    rospy.init_node("print_recognition", anonymous=True)
    count = int(rospy.get_param("~count", 2))
    topic = rospy.get_param("~topic", "/textile_recognizer/result")
    timeout = float(rospy.get_param("~timeout", 120.0))
    state = {"ok": 0, "failed": 0}

    def on_result(msg):
        if not msg.success:
            state["failed"] += 1
            print("[recognition] frame at t=%.2f s: no result: %s" % (msg.header.stamp.to_sec(), msg.message), flush=True)
            return
        state["ok"] += 1
        print("[recognition] frame at t=%.2f s: textile '%s' (id %d) held at (%.3f, %.3f) m, view %.0f deg, "
              "score %.2f, confidence %.2f, %.0f ms" % (msg.header.stamp.to_sec(), msg.textile_name, msg.textile_id,
                                                        msg.hold_x, msg.hold_y, msg.view_angle_deg, msg.score,
                                                        msg.confidence, msg.processing_ms), flush=True)
        for name, kind, pose in zip(msg.grasp_names, msg.grasp_kinds, msg.grasp_poses.poses):
            p, q = pose.position, pose.orientation
            print("    %-22s %-6s in %s: position (%+.3f, %+.3f, %+.3f) m, orientation (x %.3f, y %.3f, z %.3f, w %.3f)"
                  % (name, kind, msg.header.frame_id, p.x, p.y, p.z, q.x, q.y, q.z, q.w), flush=True)

    rospy.Subscriber(topic, RecognitionResult, on_result, queue_size=10)
    end = time.time() + timeout
    while not rospy.is_shutdown() and state["ok"] < count and time.time() < end:
        time.sleep(0.1)
    if state["ok"] < count:
        print("[recognition] only %d of %d results within %.0f s (%d failures)" % (state["ok"], count, timeout,
                                                                               state["failed"]), flush=True)
        rospy.signal_shutdown("timeout")
        sys.exit(1)
    rospy.signal_shutdown("done")


if __name__ == "__main__":
    main()
