"""Reading and writing calibration logs (MCAP) and pipelines."""
