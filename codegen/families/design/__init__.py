"""Offline gain design (numbers, not symbols): one module per seed, on shared sampling machinery.

    configurations   sampling of the joint ranges, c0(q) by the higher-order power method,
                     refinement of maxima (shared by all)
    reduced_order    seed 000: k0 (12), scheduled k_r (16), the design report, the noise-aware k0
    noise            predicted estimation error under sensor noise and model uncertainty
    ii               seed 003: constants and bounds of the I&I speed and AOV observers
    elastic          seed 004: companion, Ciccarella-Germani, Tomei and Spong gains

Imports only casadi, numpy, scipy, ``codegen.core.symbolic`` and ``codegen.core.cache`` (never the observers).
"""
from .configurations import ConfigurationStats, c0_batch
from .elastic import (ciccarella_germani_gains, companion_gains, spong_fast_gains, spong_fl_gains,
                      tomei_K1)
from .ii import IIAovDesign, IISpeedDesign, ii_aov_bounds, ii_speed_bounds
from .noise import NoiseAwareDesign, nicosia_tomei_noise_gains, sensor_sigma, switched_gains
from .reduced_order import (ReducedOrderDesign, model_statistics, reduced_order_design, reduced_order_gain,
                            scheduled_gains, torque_statistics)

__all__ = ["ConfigurationStats", "c0_batch", "ciccarella_germani_gains", "companion_gains",
           "spong_fast_gains", "spong_fl_gains", "tomei_K1", "IIAovDesign", "IISpeedDesign",
           "ii_aov_bounds", "ii_speed_bounds", "ReducedOrderDesign", "reduced_order_gain",
           "scheduled_gains", "NoiseAwareDesign", "nicosia_tomei_noise_gains", "sensor_sigma",
           "model_statistics", "reduced_order_design", "switched_gains", "torque_statistics"]
