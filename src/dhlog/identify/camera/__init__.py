"""A camera as an instrument, from its log to its calibration: the log read (`frames`: images,
intrinsics, the board detected in each frame, the encoders at each), the measurement in pixels
(`pixels`), PnP poses and the start (`poses`), the hand-eye product (`hand_eye`), its checks
(`checks`), the held-out check in pixels and mm (`holdout`), the recording's view (`view`) and
the flow (`flow`); the board, the intrinsics and the result blocks are `dhlog.vision`'s.
"""
