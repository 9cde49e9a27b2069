"""Offline gain design (numbers, not symbols): one module per seed, on shared sampling machinery.

    configurations   sampling of the joint ranges, c0(q) by the higher-order power method,
                     refinement of maxima (shared by all)
    reduced_order    seed 000: k0 (12), scheduled k_r (16), the design report
    ii               seed 003: constants and bounds of the I&I speed and AOV observers
    elastic          seed 004: companion, Ciccarella-Germani, Tomei and Spong gains

Imports only casadi, numpy, scipy and ``codegen.symbolic`` (never the observers).
"""
from .configurations import ConfigurationStats, c0_batch
from .elastic import (ciccarella_germani_gains, companion_gains, spong_fast_gains, spong_fl_gains,
                      tomei_K1)
from .ii import IIAovDesign, IISpeedDesign, ii_aov_bounds, ii_speed_bounds
from .reduced_order import ReducedOrderDesign, reduced_order_gain, scheduled_gains

__all__ = ["ConfigurationStats", "c0_batch", "ciccarella_germani_gains", "companion_gains",
           "spong_fast_gains", "spong_fl_gains", "tomei_K1", "IIAovDesign", "IISpeedDesign",
           "ii_aov_bounds", "ii_speed_bounds", "ReducedOrderDesign", "reduced_order_gain",
           "scheduled_gains"]
