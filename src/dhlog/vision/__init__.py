"""A camera as an instrument: the pinhole camera with its lens distortion, the calibration
targets (ChArUco and ArUco boards, checkerboards) and their detection in images (OpenCV), and
a calibration's product (`report`)."""
