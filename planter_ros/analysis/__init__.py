"""A season of recordings: `planter analyze` replays every bag under some paths on Dask
distributed (a local cluster or an existing one) into two Parquet tables, `plants` and `bags`
(doc/analysis.md). `bags` finds the bags, `tables` turns replay's JSON into Arrow tables,
`task` is what a worker runs (`model_code` its version), `engine` starts or joins the cluster
(`worker_plugin` ties a local cluster's workers to it), `season` keeps the tables under --out
and decides what is left to do, `progress` reports on stderr.
"""

# the submodules (imported by name, never here)
__all__ = ['bags', 'engine', 'model_code', 'progress', 'season', 'simulate', 'tables',
           'task']
