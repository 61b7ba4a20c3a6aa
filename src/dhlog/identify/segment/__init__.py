"""The log made ready: the measurement table segmented into sweeps (`segment`), the clock offset
(`timing`), per-sample arrays read a block at a time (`persample`).
"""
