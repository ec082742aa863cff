"""The OpenRover robot controller (NuttX ``rover_control`` on the LPC4337): kinematics and odometry."""
