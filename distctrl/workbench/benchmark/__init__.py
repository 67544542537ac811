"""The height-control benchmark (issue 41, ``distctrl benchmark``, docs/benchmark.md): a standard suite of
plates, sensors, drives and feeds (:mod:`.suite`), the contestants (:mod:`.contestants`), the figures of a
run (:mod:`.metrics`), running the suite locally or on a dask cluster (:mod:`.run`) and its outputs
(:mod:`.output`: CSV, plots, HTML report).

Deliberately empty: import the modules directly.
"""
