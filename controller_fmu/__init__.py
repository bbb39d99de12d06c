"""The paper's LQ feedforward-feedback tracking controller and its FMU."""
from .design import TrackingDesign, lq_tracking_design

__all__ = ["TrackingDesign", "lq_tracking_design"]
