"""Stored sequences written back out in a file format (BVH)."""
