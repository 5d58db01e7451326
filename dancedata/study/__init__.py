"""The study layer: keyframes, evaluate and experiment runs read stores, call the pure methods and
metrics, and write results.
"""
