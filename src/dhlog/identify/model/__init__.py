"""What the model holds and carries: relations held (`relations`, `pairs`), terms beyond the
geometry (`select`, `beyond`), parameters the data cannot see held (`hold`).
"""
