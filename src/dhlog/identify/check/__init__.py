"""The result checked: at every sample (`validate`), at held-out poses (`holdout`) and on another
session's footing (`footing`).
"""
