"""Derived data into a new version: ``featurize`` (the feature families), ``segment`` (measures)
and ``stats`` (normalisation).
"""
