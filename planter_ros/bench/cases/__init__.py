"""Bench case modules; importing one registers its cases (see planter_ros.bench.registry)."""
