"""The simulated camera's HTTP side: the server and listener, the VAPIX endpoints, the MJPEG stream (ROS-free)."""
