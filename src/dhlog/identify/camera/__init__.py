"""A camera calibration: PnP poses and the start (`poses`), the flow (`flow`), the hand-
eye product (`hand_eye`), its checks (`checks`), the held-out check in pixels and mm
(`holdout`) and the recording's view (`view`); the result blocks are `dhlog.vision.report`'s.
"""
