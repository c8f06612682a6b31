#!/usr/bin/python3
"""tools/ensemble_contacts.py --list on a synthetic ensemble directory (built in a temporary
directory, removed after): a leader drives 30 m east, a left quarter circle of radius 10 m,
then north; follower f1 drives the same track 0.5 m to its right. f1 touches a tree outside
the bend; the leader and f1 touch a rock beside the first straight. Each line's numbers are the
geometry's: the edge distances, f1 0.5 m nearer the tree than the leader was, the bend's side,
the speed and steering of the frame, and whether the leader touched the obstacle.

    /usr/bin/python3 tests/ensemble/test_ensemble_contacts.py

Needs Debian's python3-numpy. Exit status 0 when every check passes.
"""
import csv
import math
import pathlib
import subprocess
import sys
import tempfile
import unittest

sys.dont_write_bytecode = True
TOOL = pathlib.Path(__file__).resolve().parents[2] / "tools" / "ensemble_contacts.py"
FIELDS = ("frame,time_s,vehicle,x,y,z,qw,qx,qy,qz,vx,vy,vz,speed_mps,steering,throttle,"
          "braking,gear,engine_speed_rpm").split(",")
RADIUS = 10.0
STRAIGHT = 30.0
LENGTH = STRAIGHT + math.pi / 2 * RADIUS + 30.0


def pose(s, right=0.0):
    """The point `right` metres right of the track at arc s, and the track's heading."""
    if s <= STRAIGHT:
        x, y, yaw = s, 0.0, 0.0
    elif s <= STRAIGHT + math.pi / 2 * RADIUS:
        a = (s - STRAIGHT) / RADIUS
        x, y, yaw = STRAIGHT + RADIUS * math.sin(a), RADIUS - RADIUS * math.cos(a), a
    else:
        x, y, yaw = STRAIGHT + RADIUS, RADIUS + s - STRAIGHT - math.pi / 2 * RADIUS, math.pi / 2
    return x + right * math.sin(yaw), y - right * math.cos(yaw), yaw


class ContactList(unittest.TestCase):
    def test_each_contact_against_the_leaders_track(self):
        with tempfile.TemporaryDirectory() as tmp:
            out = pathlib.Path(tmp)
            run = out / "runs" / "7_rigid"
            run.mkdir(parents=True)
            (out / "courses").mkdir()
            # The tree outside the bend's middle (arc STRAIGHT + 5 pi / 2, heading 45 degrees),
            # its edge 3 m right of the leader's track; the rock 2 m left of the track at x=10.
            bend_s = STRAIGHT + math.pi / 4 * RADIUS
            bx, by, yaw = pose(bend_s, right=3.0 + 4.0)
            (out / "courses" / "7_rigid.yaml").write_text(
                "obstacles:\n"
                f"  - {{id: tree3, label: tree, shape: cylinder, position: [{bx:.6f}, {by:.6f}], "
                "radius_m: 4, height_m: 6}\n"
                "  - {id: rock1, label: rock, shape: cylinder, position: [10, 3], radius_m: 1, "
                "height_m: 1}\n")
            with open(run / "vehicles.csv", "w", newline="") as f:
                w = csv.writer(f)
                w.writerow(FIELDS)
                for k in range(int(LENGTH / 0.05)):  # 5 m/s, a frame every 0.01 s
                    s = k * 0.05
                    for v, right in (("l1", 0.0), ("f1", 0.5)):
                        x, y, h = pose(s, right)
                        w.writerow([k, f"{k * 0.01:.2f}", v, x, y, 0.5, math.cos(h / 2), 0, 0,
                                    math.sin(h / 2), 0, 0, 0, 5.0, 0.25 if v == "f1" else 0.2,
                                    0.3, 0, 1, 1500])
            t_bend = bend_s / 5.0
            (run / "events.csv").write_text(
                "frame,time_s,kind,vehicle,detail\n"
                "200,2.00,collision,l1,obstacle=rock1 impulse_ns=10 at=10/2/0.5\n"
                "201,2.01,collision,l1,obstacle=rock1 impulse_ns=10 at=10/2/0.5\n"
                "200,2.00,collision,f1,obstacle=rock1 impulse_ns=10 at=10/2/0.5\n"
                f"{int(t_bend * 100)},{t_bend:.2f},collision,f1,obstacle=tree3 impulse_ns=5 "
                "at=0/0/1\n")
            lines = subprocess.run(["/usr/bin/python3", str(TOOL), "--list", str(out)],
                                   check=True, capture_output=True, text=True).stdout.splitlines()
            self.assertEqual(len(lines), 3, lines)  # the leader's second rock contact: once
            leader_rock, f1_rock, f1_tree = lines
            self.assertTrue(leader_rock.startswith("7_rigid l1 rock1 (rock, r 1.00 m) t 2.00 s: "
                                                   "edge 2.00 m, leader's 2.00 m there, nearer "
                                                   "by +0.00 m; turn +0 deg, straight"), leader_rock)
            self.assertIn("leader touched it: yes", leader_rock)
            # f1 is 0.5 m right of the leader, the rock is on the left: 0.5 m farther.
            self.assertIn("edge 2.50 m, leader's 2.00 m there, nearer by -0.50 m", f1_rock)
            self.assertTrue(f1_tree.startswith("7_rigid f1 tree3 (tree, r 4.00 m)"), f1_tree)
            self.assertIn("edge 2.50 m, leader's 3.00 m there, nearer by +0.50 m", f1_tree)
            # 10 m of arc on a 10 m radius: 57 degrees to the left, the tree on the right.
            self.assertIn("turn +57 deg, outside; speed 5.00 m/s, steering +0.25; "
                          "leader touched it: no", f1_tree)


if __name__ == "__main__":
    unittest.main()
