#!/usr/bin/python3
"""Prints the textile_recognizer's results (textile, hold point, grasp poses) and exits after N of them.

Usage (inside a ROS graph): print_recognition.py [_count:=N] [_topic:=/textile_recognizer/result]
Exit status 0 when N successful results arrived, or when at least one did and none followed for
_idle_timeout:=S wall seconds (default 15: the recognizer drops frames while busy, so a short bag can
give fewer than N); 1 when none arrived within _timeout:=S wall seconds.
With ~truth (a bag's .truth.yaml loaded by rosparam, as record_drape_bag writes it) every result is also
compared with the ground truth: the largest distance of a grasp pose from the true point, names relabelled
by the textile's mirror symmetry as in test/ros/test_replay_recognition.cpp.
"""
import sys
import time

import rospy
from textile_handling.msg import RecognitionResult


def truth_errors(truth, msg):
    """Largest grasp-pose distance [m] from the truth, and the truth's names, under the best mirror
    relabelling that maps the true hold point closest to the reported one (None without a match)."""
    hold = truth["hold_xy"]
    centre = truth["bounding_box_centre"]
    textile = truth["named_points_textile"]
    gripper = truth["views"][0]["named_points_in_gripper"]

    def mirrored(m, p):
        return (2 * centre[0] - p[0] if m & 1 else p[0], 2 * centre[1] - p[1] if m & 2 else p[1])

    def dist2(a, b):
        return sum((x - y) ** 2 for x, y in zip(a, b))

    d = [dist2(mirrored(m, hold), (msg.hold_x, msg.hold_y)) ** 0.5 for m in range(4)]
    best = None
    for m in range(4):
        if d[m] > min(d) + 1e-6:
            continue
        worst = 0.0
        for name, pose in zip(msg.grasp_names, msg.grasp_poses.poses):
            if name not in textile:
                continue
            q = mirrored(m, textile[name])
            truth_name = next((n for n, p in textile.items() if dist2(p, q) < 1e-12), None)
            if truth_name is None or truth_name not in gripper:
                continue
            p = pose.position
            worst = max(worst, dist2((p.x, p.y, p.z), gripper[truth_name]) ** 0.5)
        if best is None or worst < best:
            best = worst
    return best


def main():
    rospy.init_node("print_recognition", anonymous=True)
    count = int(rospy.get_param("~count", 2))
    topic = rospy.get_param("~topic", "/textile_recognizer/result")
    timeout = float(rospy.get_param("~timeout", 120.0))
    idle_timeout = float(rospy.get_param("~idle_timeout", 15.0))
    truth = rospy.get_param("~truth", None)
    state = {"ok": 0, "failed": 0, "last": None}

    def on_result(msg):
        if not msg.success:
            state["failed"] += 1
            print("[recognition] frame at t=%.2f s: no result (%s): %s"
                  % (msg.header.stamp.to_sec(), msg.reason_code, msg.message), flush=True)
            for w in msg.warnings:
                print("    warning: %s" % w, flush=True)
            return
        state["ok"] += 1
        state["last"] = time.time()
        for w in msg.warnings:
            print("    warning: %s" % w, flush=True)
        print("[recognition] frame at t=%.2f s: textile '%s' (id %d) held at (%.3f, %.3f) m, view %.0f deg, "
              "score %.2f, confidence %.2f, %d image(s) fused, %.0f ms"
              % (msg.header.stamp.to_sec(), msg.textile_name, msg.textile_id, msg.hold_x, msg.hold_y,
                 msg.view_angle_deg, msg.score, msg.confidence, msg.images_fused, msg.processing_ms), flush=True)
        n = len(msg.grasp_names)
        evidence = list(msg.grasp_evidence) if len(msg.grasp_evidence) == n else ["?"] * n
        bound = list(msg.grasp_uncertainty_m) if len(msg.grasp_uncertainty_m) == n else [-1.0] * n
        safe = list(msg.grasp_safe) if len(msg.grasp_safe) == n else [False] * n
        for name, kind, pose, ev, u, ok in zip(msg.grasp_names, msg.grasp_kinds, msg.grasp_poses.poses, evidence, bound, safe):
            p, q = pose.position, pose.orientation
            print("    %-22s %-6s in %s: position (%+.3f, %+.3f, %+.3f) m, orientation (x %.3f, y %.3f, z %.3f, w %.3f); "
                  "from %s, within %.2f m%s"
                  % (name, kind, msg.header.frame_id, p.x, p.y, p.z, q.x, q.y, q.z, q.w, ev, u, ", SAFE" if ok else ""),
                  flush=True)
        if truth:
            err = truth_errors(truth, msg)
            if err is not None:
                print("    against the bag's ground truth: largest grasp-pose distance %.3f m" % err, flush=True)

    rospy.Subscriber(topic, RecognitionResult, on_result, queue_size=10)
    end = time.time() + timeout
    while not rospy.is_shutdown() and state["ok"] < count and time.time() < end:
        if state["last"] is not None and time.time() - state["last"] > idle_timeout:
            print("[recognition] %d of %d results; no more for %.0f s" % (state["ok"], count, idle_timeout), flush=True)
            break
        time.sleep(0.1)
    if state["ok"] == 0:
        print("[recognition] only %d of %d results within %.0f s (%d failures)" % (state["ok"], count, timeout,
                                                                               state["failed"]), flush=True)
        rospy.signal_shutdown("timeout")
        sys.exit(1)
    rospy.signal_shutdown("done")


if __name__ == "__main__":
    main()
