"""Each joint alone: its sweeps' axis fits (`sweeps`) and what the log and the fits say of the
run's inputs (`checks`).
"""
