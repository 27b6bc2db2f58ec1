"""Reports a person can read: the calibration report as one self-contained HTML file."""

from camkit.calib.uncertainty import projection_uncertainty
from camkit.report.html import write_report

__all__ = ["projection_uncertainty", "write_report"]
