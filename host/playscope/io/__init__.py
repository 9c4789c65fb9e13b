"""Recordings in: session folders, CSV and ROS-bag import, a recording file read in place,
marker tracking in the video, and the check every input file passes."""
