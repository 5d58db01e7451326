"""Running independent tasks: serially, in a local process pool, or on a Dask cluster.

- :mod:`dancedata.exec.threads` pins BLAS / OpenMP / numba threads in worker processes.
- :mod:`dancedata.exec.executors` maps a function over tasks on one of three engines.
- :mod:`dancedata.exec.tasks` records finished tasks durably so an interrupted run resumes.
"""
