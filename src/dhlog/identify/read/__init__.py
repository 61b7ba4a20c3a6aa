"""The DH model read off the fitted axes: the line geometry (`extract`, `hayati`), its covariance
and what is fixed (`propagate`, `uncertainty`, `conditioning`; the analytic result's:
`analytic`).
"""
