"""Reports a person can read: the calibration and rig reports, each one self-contained HTML file."""

from camkit.calib.uncertainty import projection_uncertainty
from camkit.report.html import write_report
from camkit.report.rig import write_rig_report

__all__ = ["projection_uncertainty", "write_report", "write_rig_report"]
