"""
Recording: rosbag2 MCAP bags, CDR message encoding, CSV files and the topic table.

No ROS: bags are written and read with the ``mcap`` library and our own CDR
layouts, so the core can record and replay without rclpy.
"""
