"""Identification reports: self-contained HTML with embedded figures, and metrics JSON.

=======================  ================================================================
``Report``               build an HTML report from sections, tables and figures
``write_metrics``        write the figures of a report's tables as ``metrics.json``
``write_report_folder``  write ``index.html`` and ``metrics.json`` atomically (all or nothing)
``model_report``         Bode, pole-zero and simulation report of any model on data
``uncertainty_section``  the model's response with +-2 std bands and its relative std
``settings_section``     the command line, settings and version that made a report
``modal_section``        the modes (frequency, damping) of a linear model as a table
``frd_fit_report``       the report of a model fitted to a measured frequency response
=======================  ================================================================
"""

from .frd_report import frd_fit_report
from .html import Report, write_metrics, write_report_folder
from .model_report import hysteresis_model_report, lti_model_report, model_report
from .modes import modal_section
from .provenance import settings_section
from .uncertainty import magnitude_band, uncertainty_section

__all__ = [
    "Report",
    "write_metrics",
    "write_report_folder",
    "model_report",
    "lti_model_report",
    "hysteresis_model_report",
    "uncertainty_section",
    "magnitude_band",
    "settings_section",
    "modal_section",
    "frd_fit_report",
]
