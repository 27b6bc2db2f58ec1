"""Reports a person can read: the calibration report as one self-contained HTML file."""

from camkit.report.html import projection_uncertainty, write_report

__all__ = ["projection_uncertainty", "write_report"]
