"""Sensor models: GNSS (ZED-F9P-like), IMU (MTi-like), wheel odometry, depth (D455-like)."""
