"""Filter workbench: compare sensor-filter configurations on a recorded or synthetic signal.

The documents (FCT-M3 ch. 4, Figs. 9-17) show the filters on one test: a sensor crosses an
obstacle about 2.8 mm high with distance control disabled, and the raw and filtered sensor data are
overlaid. This package reproduces that test offline for any set of :class:`FilterConfig`:

* :func:`parse_filter_spec` turns the CLI text ``MOVING_AVERAGE:n_cycles=10,20,40`` into configs,
* :func:`obstacle_signal` is the documents' synthetic test signal (seeded noise),
* :func:`load_recording` reads a sensor recording (plain CSV or a distctrl trace CSV),
* :func:`compare` runs every filter (:meth:`SensorFilter.apply`, the cycle core's own law) and
  measures noise RMS, delay (50 %), dead time (10 %) and overshoot,
* :func:`format_table` and :func:`plot_overlay` present the result (docs/workbench-filters.md).

Nothing here touches the cycle path; errors are :class:`WorkbenchError` (a ``DistCtrlError``)
whose messages name the spec, file, line or column and what is allowed.

The modules, by role (this face re-exports every name, so ``from distctrl.workbench.filters import ...``
works as before):

* ``spec``: the errors, the spec parser and :data:`DEFAULT_SPECS`;
* ``signals``: :func:`obstacle_signal` and :func:`find_edges`;
* ``recording``: :class:`Recording` and :func:`load_recording`;
* ``model``: :func:`compare` and the metrics (:func:`signal_noise_rms`, :func:`warmup_samples`);
* ``result``: :class:`FilterResult` (``to_dict``, ``to_csv``, ``plot``) and :func:`plot_overlay`;
* ``text``: :func:`format_table`, :func:`write_results_csv` and :func:`results_dicts`.
"""
from __future__ import annotations

from ..plotfiles import PLOT_SUFFIXES  # noqa: F401  (part of the API)
from .model import compare, signal_noise_rms, warmup_samples
from .recording import Recording, load_recording
from .result import FilterResult, check_plot_path, plot_overlay
from .signals import find_edges, obstacle_signal
from .spec import (_RANGES, DEFAULT_SPECS, KEY_ALIASES, KEY_ORDER, KEYS_BY_TYPE, SPEC_SYNTAX,  # noqa: F401
                   FilterSpecError, RecordingError, RecordingWarning, WorkbenchError, WorkbenchWarning,
                   default_configs, parse_filter_spec, parse_filter_specs)
from .text import RESULT_CSV_COLUMNS, TABLE_COLUMNS, format_table, results_dicts, write_results_csv  # noqa: F401

__all__ = [
    "WorkbenchError", "FilterSpecError", "RecordingError", "WorkbenchWarning", "RecordingWarning",
    "FilterResult", "Recording", "DEFAULT_SPECS", "SPEC_SYNTAX",
    "parse_filter_spec", "parse_filter_specs", "default_configs", "obstacle_signal", "load_recording",
    "find_edges", "compare", "signal_noise_rms", "warmup_samples", "format_table", "write_results_csv",
    "check_plot_path", "plot_overlay",
]
