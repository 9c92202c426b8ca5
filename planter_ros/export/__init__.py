"""The as-planted map as files, every format in this one place: GeoJSON and CSV (`geojson_csv`,
doc/planting_quality.md) and the formats farm software imports (doc/exports.md): an ESRI
Shapefile (`shapefile`, point per plant, WGS 84) and ISO 11783-10 task data (`isoxml`, an
as-planted task with its binary time log), from one replay (`planter replay`: `replay`) or a
season of them (`planter analyze`: `season`, from its tables). `runs` is what the farm formats
take: one recording's plants as records. Pure Python and numpy, no ROS.
"""

from planter_ros.output_files import OutputError

__all__ = ['ExportError']


class ExportError(OutputError):
    """Plants a format cannot hold as asked (one line: what and the allowed range): an output
    that cannot be written as asked, so the command line reports it as bad input."""
