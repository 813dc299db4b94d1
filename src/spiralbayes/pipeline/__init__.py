"""Every end-to-end run, for the command line and for notebooks.

:mod:`~spiralbayes.pipeline.scan_command` and :mod:`~spiralbayes.pipeline.sample_command` run ``scan``
and ``sample`` from a configuration, reading it with :mod:`~spiralbayes.pipeline.inputs` and writing
with :mod:`~spiralbayes.pipeline.outputs`; :mod:`~spiralbayes.pipeline.demo` holds the demo and the
frank fit with plots; :mod:`~spiralbayes.pipeline.limits` the exclusion limits,
completeness and forecasts; :mod:`~spiralbayes.pipeline.compare` the comparison with CASA's CLEAN
images (image-plane comparisons). The command line (:mod:`spiralbayes.cli`) only parses arguments and calls
these. Outputs are written atomically (temporary file, then rename, with the user's umask), JSON
outputs are strict (NaN written as ``null``), and a scan's configuration record is written only
once the scan it describes has finished.
"""

from .compare import CompareResult, compare_table, run_compare_config
from .demo import DemoResult, run_axisym, run_demo
from .inputs import learned_templates, load_axisymmetric, load_data, load_maps, load_templates, select_templates
from .outputs import save_figure, write_scan_outputs
from .sample_command import run_sample_config
from .scan_command import ScanRun, run_scan, run_scan_config
from .limits import LimitsRun, run_forecast, run_limits, run_limits_config, run_limits_demo

__all__ = [
    "CompareResult",
    "DemoResult",
    "LimitsRun",
    "ScanRun",
    "compare_table",
    "learned_templates",
    "load_axisymmetric",
    "load_data",
    "load_maps",
    "load_templates",
    "run_axisym",
    "run_compare_config",
    "run_demo",
    "run_forecast",
    "run_limits",
    "run_limits_config",
    "run_limits_demo",
    "run_sample_config",
    "run_scan",
    "run_scan_config",
    "save_figure",
    "select_templates",
    "write_scan_outputs",
]
