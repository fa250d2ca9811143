"""Work beyond one process: re-analysis of a site's archive and parameter studies on a
Dask cluster (``dask.distributed``: an embedded ``LocalCluster`` or a scheduler's address).

The physics knows nothing of Dask: the tasks (``tasks.py``) call the same functions a
single process calls (``service.physics``), in batches; this package splits the work,
sends it, stores what comes back and reports progress.
"""
