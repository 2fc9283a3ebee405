"""The simulated camera's RTSP H.264 side (VAPIX RTSP API): server, sessions, RTP/RTCP (ROS-free)."""
