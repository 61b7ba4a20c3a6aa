"""Identification: per-joint fits → analytic start (seed 000) → maximum-likelihood fit of the
whole model to every sample → the DH model and its covariance."""
