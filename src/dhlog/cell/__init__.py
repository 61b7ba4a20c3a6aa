"""Work in the robot cell around a calibration: planning a session and compensating targets."""
