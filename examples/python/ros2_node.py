"""An rclpy node: sensor_msgs/LaserScan in, isoline's curves out as a
visualization_msgs/MarkerArray (one LINE_STRIP a curve, in the scan's frame).

    ros2 run ... or: python examples/python/ros2_node.py --ros-args -r scan:=/scan

Each scan is pushed to an isoline.Stream, so consecutive scans warm-start each other as
in the daemon; give the Stream a pose (from tf) and `accumulate` to refine over frames.
The reconstruction releases the GIL, so a MultiThreadedExecutor keeps serving other
callbacks meanwhile.

ROS 2 is not installed where isoline is built and tested: this node is an example. The
isoline calls it makes (Frame.from_scan, Stream.push, Result.polylines) are the ones
python/tests covers.
"""

import isoline
import rclpy
from geometry_msgs.msg import Point
from rclpy.node import Node
from sensor_msgs.msg import LaserScan
from visualization_msgs.msg import Marker, MarkerArray


class CurveNode(Node):
    def __init__(self):
        super().__init__("isoline_curves")
        self.stream = isoline.Stream()
        self.frame = 0
        self.previous_markers = 0
        self.pub = self.create_publisher(MarkerArray, "curves", 10)
        self.create_subscription(LaserScan, "scan", self.on_scan, 10)

    def on_scan(self, msg: LaserScan):
        stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        try:
            frame = isoline.Frame.from_scan(
                msg.ranges,
                msg.angle_min,
                msg.angle_increment,
                msg.range_min,
                msg.range_max,
                t=stamp,
                frame=self.frame,
            )
            result = self.stream.push(frame)
        except ValueError as e:
            self.get_logger().warning(f"scan {self.frame}: {e}")
            return
        finally:
            self.frame += 1
        for w in result.warnings:
            self.get_logger().info(f"scan {self.frame - 1}: {w}")
        out = MarkerArray()
        for i, (curve, closed) in enumerate(zip(result.polylines, result.closed)):
            m = Marker()
            m.header = msg.header
            m.ns, m.id = "isoline", i
            m.type, m.action = Marker.LINE_STRIP, Marker.ADD
            m.scale.x = 0.02
            m.color.r, m.color.g, m.color.b, m.color.a = (0.1, 0.4, 1.0, 1.0)
            m.pose.orientation.w = 1.0
            pts = list(curve) + ([curve[0]] if closed else [])
            m.points = [Point(x=float(x), y=float(y), z=0.0) for x, y in pts]
            out.markers.append(m)
        # Curves of the last scan that this one does not have are deleted.
        for i in range(len(result.polylines), self.previous_markers):
            m = Marker()
            m.header, m.ns, m.id, m.action = msg.header, "isoline", i, Marker.DELETE
            out.markers.append(m)
        self.previous_markers = len(result.polylines)
        self.pub.publish(out)


def main():
    rclpy.init()
    node = CurveNode()
    try:
        rclpy.spin(node)
    finally:
        node.destroy_node()
        rclpy.shutdown()


if __name__ == "__main__":
    main()
