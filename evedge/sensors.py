"""Event-sensor presets, defined once: resolution, pixel pitch, a nominal lens and typical pixel settings.

Every other table of sensors in evedge derives from :data:`SENSOR_MODELS`
(:data:`evedge.events.SENSOR_PRESETS` the sizes, :data:`evedge.sim.SENSOR_PRESETS`
the sizes and intrinsics; a scene's ``[events] preset`` the thresholds and
refractory period).

Thresholds are log-intensity steps ``C = ln(1 + c)`` for a documented
contrast ``c`` (a relative change ``Delta I / I``). Resolutions and pixel
pitches are the makers' documented figures. Thresholds, mismatch and
refractory period are bias-dependent on every one of these chips (the makers
document them at their default biases, when at all); each model's
``documented`` field lists which of its figures are documented by the maker
or the sensor's paper, the others are typical values used in the literature
and in simulators (ESIM, v2e), stated as such.

Sources
-------
- dvs128: P. Lichtsteiner, C. Posch, T. Delbruck, "A 128x128 120 dB 15 us
  latency asynchronous temporal contrast vision sensor", IEEE JSSC 43(2), 2008:
  128x128, 40 um pixels, threshold mismatch 2.1 % contrast (1 sigma).
- davis240: C. Brandli et al., "A 240x180 130 dB 3 us latency global shutter
  spatiotemporal vision sensor", IEEE JSSC 49(10), 2014: 240x180, 18.5 um
  pixels; iniVation DAVIS240 specification: contrast sensitivity 11 %.
  Intrinsics: the Event Camera Dataset's calibration of its DAVIS240C.
- davis346: iniVation DAVIS346 specification (datasheet): 346x260, 18.5 um
  pixels, contrast sensitivity 14.3 % (ON) and 22.5 % (OFF) at default biases.
- dvxplorer: iniVation DVXplorer specification: 640x480, 9 um pixels (Samsung
  DVS Gen3 chip, B. Son et al., ISSCC 2017).
- gen3: Prophesee Gen3 VGA (PPS3MVCD / Gen3.1) specification: 640x480, 15 um
  pixels.
- gen4: T. Finateu et al., "A 1280x720 back-illuminated stacked temporal
  contrast event-based vision sensor with 4.86 um pixels", ISSCC 2020
  (Prophesee Gen4 / Sony IMX636 family): 1280x720, 4.86 um pixels.

The nominal lenses (focal length in mm, giving ``fx = fy = f / pitch``) are a
convenience for 3-D scenes, not part of the sensors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class SensorModel:
    """One sensor preset.

    Attributes
    ----------
    name : str
    width, height : int
        Resolution (px).
    pixel_pitch_um : float
        Pixel pitch (um).
    fx, fy, cx, cy : float
        Pinhole intrinsics (px) of a nominal lens.
    contrast_pos, contrast_neg : float
        ON / OFF thresholds in log-intensity units (``ln(1 + contrast)``).
    contrast_sigma : float
        Per-pixel threshold mismatch (std, log units).
    refractory_us : float
        Refractory period (us).
    documented : tuple of str
        The fields that are the maker's (or the chip paper's) documented
        figures; the others are typical values.
    source : str
        Where the documented figures come from (see the module docstring).
    """

    name: str
    width: int
    height: int
    pixel_pitch_um: float
    fx: float
    fy: float
    cx: float
    cy: float
    contrast_pos: float
    contrast_neg: float
    contrast_sigma: float
    refractory_us: float
    documented: tuple[str, ...]
    source: str

    @property
    def event_params(self) -> dict[str, float]:
        """The pixel settings as :class:`evedge.sim.ConverterParams` keywords."""
        return dict(contrast_pos=self.contrast_pos, contrast_neg=self.contrast_neg,
                    contrast_sigma=self.contrast_sigma, refractory_us=self.refractory_us)


def _log(contrast: float) -> float:
    return round(math.log1p(contrast), 4)


def _model(name, width, height, pitch_um, lens_mm, c_on, c_off, sigma, refractory_us, documented, source,
           intrinsics=None):
    f = lens_mm * 1e3 / pitch_um
    fx, fy, cx, cy = intrinsics if intrinsics else (round(f, 3), round(f, 3), (width - 1) / 2, (height - 1) / 2)
    return SensorModel(name, width, height, pitch_um, fx, fy, cx, cy, _log(c_on), _log(c_off), sigma,
                       refractory_us, documented, source)


_SIZE = ("width", "height", "pixel_pitch_um")

#: The presets, by name.
SENSOR_MODELS: dict[str, SensorModel] = {m.name: m for m in (
    # 4.5 mm lens on 40 um pixels: fx = 112.5 (the previous dvs128 preset)
    _model("dvs128", 128, 128, 40.0, 4.5, 0.15, 0.15, round(math.log1p(0.021), 4), 100.0,
           _SIZE + ("contrast_sigma",), "Lichtsteiner et al., IEEE JSSC 2008"),
    _model("davis240", 240, 180, 18.5, 3.7, 0.11, 0.11, 0.03, 100.0,
           _SIZE + ("fx", "fy", "cx", "cy", "contrast_pos", "contrast_neg"),
           "Brandli et al., IEEE JSSC 2014; iniVation DAVIS240 specification; Event Camera Dataset calibration",
           intrinsics=(199.092, 198.829, 132.192, 110.713)),
    # f = 260 px (the previous davis346 preset): a 4.81 mm lens
    _model("davis346", 346, 260, 18.5, 4.81, 0.143, 0.225, 0.03, 100.0,
           _SIZE + ("contrast_pos", "contrast_neg"), "iniVation DAVIS346 specification",
           intrinsics=(260.0, 260.0, 172.5, 129.5)),
    _model("dvxplorer", 640, 480, 9.0, 4.0, 0.2, 0.2, 0.03, 100.0, _SIZE,
           "iniVation DVXplorer specification; Son et al., ISSCC 2017"),
    _model("gen3", 640, 480, 15.0, 8.0, 0.2, 0.2, 0.03, 100.0, _SIZE, "Prophesee Gen3 VGA specification"),
    _model("gen4", 1280, 720, 4.86, 4.0, 0.2, 0.2, 0.03, 100.0, _SIZE, "Finateu et al., ISSCC 2020"),
)}


def sensor_model(name: str) -> SensorModel:
    """The preset called ``name`` (case-insensitive).

    Parameters
    ----------
    name : str

    Returns
    -------
    SensorModel

    Raises
    ------
    ValueError
        Unknown name (the known ones are listed).

    Examples
    --------
    >>> m = sensor_model("gen4")
    >>> (m.width, m.height)
    (1280, 720)
    """
    key = str(name).strip().lower()
    if key not in SENSOR_MODELS:
        raise ValueError(f"unknown sensor preset {name!r}; known: {sorted(SENSOR_MODELS)}")
    return SENSOR_MODELS[key]
