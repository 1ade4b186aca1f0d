#!/usr/bin/python3
# SPDX-License-Identifier: MIT
# Reads a bag with ROS's own reference implementation (Debian's python3-rosbag) and prints what
# the recording test compares with the C++ side: each topic's type and count, the peak |force| of
# each /telex/force/* topic, and the first depth image's layout.
import json
import math
import sys

import rosbag

bag = rosbag.Bag(sys.argv[1])
info = bag.get_type_and_topic_info()
out = {"topics": {t: {"type": v.msg_type, "messages": v.message_count}
                  for t, v in info.topics.items()},
       "peak_force_N": {}, "depth": None}
for topic, msg, _ in bag.read_messages():
    if topic.startswith("/telex/force/"):
        f = msg.wrench.force
        name = topic[len("/telex/force/"):]
        out["peak_force_N"][name] = max(out["peak_force_N"].get(name, 0.0),
                                        math.sqrt(f.x * f.x + f.y * f.y + f.z * f.z))
    elif topic == "/telex/depth/image_raw" and out["depth"] is None:
        out["depth"] = {"encoding": msg.encoding, "width": msg.width, "height": msg.height,
                        "step": msg.step, "bytes": len(msg.data), "seq": msg.header.seq}
print(json.dumps(out))
