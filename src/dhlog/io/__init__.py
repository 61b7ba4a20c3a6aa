"""Reading and writing: calibration logs (MCAP, rosbag2), the tracker software's exports, DH files,
pipelines, untrusted text and output paths; the writers the simulator and `dhlog import` use."""
