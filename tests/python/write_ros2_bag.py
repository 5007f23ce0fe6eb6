"""Writes a ROS 2 bag (MCAP, CDR) with the official MCAP tooling (`mcap`, `mcap-ros2-support`),
no ROS install: sensor_msgs/msg/JointState on /joint_states for two joints ("elbow" from the
input CSV, "wrist" constant) and the measured external torque as std_msgs/msg/Float64 on
/load_torque, published once per two joint states (the importer must hold it).

usage: write_ros2_bag.py IN.csv OUT.mcap    (IN: time,position,velocity,torque — the DFKI layout)
"""
import csv
import sys

from mcap_ros2.writer import Writer

JOINT_STATE = """std_msgs/Header header
string[] name
float64[] position
float64[] velocity
float64[] effort
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""
FLOAT64 = "float64 data\n"


def main(src, dst):
    with open(src, newline="") as f:
        rows = [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]
    with open(dst, "wb") as out:
        w = Writer(out)
        js = w.register_msgdef("sensor_msgs/msg/JointState", JOINT_STATE)
        fl = w.register_msgdef("std_msgs/msg/Float64", FLOAT64)
        base = 1_700_000_000 * 10**9
        for k, r in enumerate(rows):
            ns = base + round(r["time"] * 1e9)
            if k % 2 == 0:
                # the load torque arrives just before the joint state it belongs to
                w.write_message("/load_torque", fl, {"data": 0.5 * r["torque"]}, log_time=ns - 1000, publish_time=ns - 1000)
            msg = {
                "header": {"stamp": {"sec": ns // 10**9, "nanosec": ns % 10**9}, "frame_id": "base"},
                "name": ["wrist", "elbow"],
                "position": [0.1, r["position"]],
                "velocity": [0.0, r["velocity"]],
                "effort": [0.0, r["torque"]],
            }
            w.write_message("/joint_states", js, msg, log_time=ns, publish_time=ns)
        w.finish()


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
