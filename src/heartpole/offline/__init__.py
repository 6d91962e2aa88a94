"""Offline RL on HeartPole: Minari datasets, the true values that off-policy evaluation estimates, estimators.

Install with ``pip install heartpole[offline]`` (Minari). ``import heartpole.offline`` itself needs only
NumPy: Minari is imported when a dataset is written or read.
"""
