"""The whole-model fit: the model (`axismodel`), its prediction (`prediction`), the passes over the
samples (`passes`), the tracker's streamed maximum likelihood (`whole`), the measurement-model
interface every instrument implements (`measure`; a camera's pixels: `identify.camera.pixels`),
the fit's start
(`samples`, `start`, `register`), linearised refits (`leaveout`) and its weights (`variance`).
"""
