"""Running independent work units: serially, in a local process pool, or on a Dask cluster.

- :mod:`dancedata.exec.threads` pins BLAS / OpenMP / numba threads in worker processes.
- :mod:`dancedata.exec.executors` maps a function over work units on one of three engines.
- :mod:`dancedata.exec.units` records finished units durably so an interrupted run resumes.
"""
