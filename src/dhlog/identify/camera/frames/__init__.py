"""A camera log read into :class:`~dhlog.identify.camera.frames.observations.Observations`: its
images and intrinsics (`imagedecode`: one payload, `images`: a topic), its cameras and small
streams found first (`camerafind`), the board detected in each frame (`detect`, in worker
processes: `framedetect`), the encoders joined at each frame (`observe`, `observations`).
"""
