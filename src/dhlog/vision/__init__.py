"""A camera as the pipeline and the result name it: the pinhole camera with its lens distortion
(`camera`), the calibration targets — ChArUco and ArUco boards, checkerboards — (`boards`;
OpenCV), and the blocks a calibration's result holds (`report`, `view`)."""
