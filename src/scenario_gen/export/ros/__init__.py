"""The Nav2 bundle's own ROS 2 programs, copied into every ``--to nav2`` export.

Each module here runs under ROS 2 Humble's Python (3.10) with rclpy and the message packages a
Nav2 install has; nothing here imports the rest of this project, and rclpy is imported only
inside ``main`` so the geometry can be tested without ROS:

- ``follow_route`` — the waypoint follower: checks the GPS waypoints through
  navsat_transform's ``fromLL``, then sends Nav2 the route ahead of the robot as
  NavigateThroughPoses goals, the points the benchmark's route observation holds.
- ``sensor_covariances`` — stamps the bridged IMU, GNSS and wheel odometry with the
  covariances of the simulator's sensor models (Gazebo's messages carry none).
- ``launch_template`` — the launch file (``launch/agrinav_field.launch.py``).
"""
