"""Event-sensor presets, defined once: resolution, pixel pitch, a nominal lens and typical pixel settings.

Every other table of sensors in evedge derives from :data:`SENSOR_MODELS`
(:data:`evedge.events.SENSOR_PRESETS` the sizes, :data:`evedge.sim.SENSOR_PRESETS`
the sizes and intrinsics; a scene's ``[events] preset`` the thresholds and
refractory period).

Thresholds are log-intensity steps ``C = ln(1 + c)`` for a contrast ``c``
(a relative change ``Delta I / I``). Thresholds, mismatch and refractory
period are set by biases on every one of these chips; the makers document
them at default biases, when at all. Each model says where each of its
figures comes from (:meth:`SensorModel.source_of`, the ``sources`` field);
``documented`` lists the fields that are the maker's or the chip paper's
figures, the others are typical values (ESIM's and v2e's defaults), stated
as such. What could and could not be checked against the makers' own text
when the presets were last revised:

- Resolutions: all documented. DVS128, DAVIS240 and Gen4 by their chip papers'
  titles; DAVIS240 and DAVIS346 also by iniVation's libcaer chip identifiers
  ("DAVIS240A ... 240x180", "DAVIS346B ... 346x260"); DVXplorer's Samsung chip
  by its paper (Son et al. 2017: "640x480 VGA-resolution DVS ... with a 9 um pixel
  pitch"; libcaer names the DVXplorer Lite's chip "Samsung ... 320x240"); Gen3 by
  Prophesee's Metavision documentation ("Gen3.1 VGA Sensor").
- Pixel pitch: DVS128 40 um (the paper's abstract and INI's DVS128 user guide:
  "128 pixels x 40 um/pixel"), DVXplorer 9 um (Son et al. 2017), Gen4 4.86 um
  (Finateu et al. 2020, title); DAVIS240/DAVIS346 18.5 um (Brandli et al. 2014 and
  iniVation's DAVIS346 specification; Son et al. 2017 also cite 18.5 um as the
  smallest DVS pixel before theirs) and Gen3 15 um (Prophesee's Gen3 VGA
  product brief) were not re-read here.
- Thresholds: only iniVation publishes them (DAVIS240 11 %, DAVIS346 14.3 % ON
  and 22.5 % OFF at default biases, in the specification sheets, not re-read
  here). Prophesee defines contrast threshold, non-uniformity and refractory
  bias in its public documentation (Metavision "Biases" page, knowledge-base
  "Event-Based Vision sensor characteristics") but gives the figures only in
  datasheets behind a customer login; the DVXplorer's are bias presets
  without a published contrast. Those thresholds are v2e's default 0.2 (log
  units; ESIM's default too), typical.
- Mismatch: DVS128's 2.1 % (1 sigma) is the paper's; the others are v2e's
  default ``sigma_thres = 0.03``, typical.
- Refractory period: no maker publishes it as a time at default biases; 100 us
  everywhere is a typical value (ESIM and v2e default to no refractory period).

Sources
-------
- Lichtsteiner, Posch, Delbruck, "A 128x128 120 dB 15 us latency asynchronous
  temporal contrast vision sensor", IEEE JSSC 43(2), 2008 (abstract: 40x40 um2
  pixels, 2.1 % threshold mismatch); INI DVS128 user guide,
  http://siliconretina.ini.uzh.ch/wiki/doku.php?id=userguide.
- Brandli, Berner, Yang, Liu, Delbruck, "A 240x180 130 dB 3 us latency global
  shutter spatiotemporal vision sensor", IEEE JSSC 49(10), 2014.
- iniVation libcaer ``davis.h`` / ``dvxplorer.h`` chip identifiers
  (https://docs.ros.org/en/jazzy/p/libcaer/); iniVation product specifications
  (https://inivation.com/support/product-specifications/).
- Son et al., "A 640x480 dynamic vision sensor with a 9 um pixel and 300 Meps
  address-event representation", ISSCC 2017 (the DVXplorer's Samsung DVS).
- Prophesee Metavision SDK documentation: supported sensors (Gen3.1 VGA,
  IMX636 HD) https://docs.prophesee.ai/stable/hw/products.html, biases
  https://docs.prophesee.ai/stable/hw/manuals/biases.html.
- Finateu et al., "A 1280x720 back-illuminated stacked temporal contrast
  event-based vision sensor with 4.86 um pixels, 1.066 GEPS readout, ...",
  ISSCC 2020 (Prophesee Gen4 / Sony IMX636).
- v2e (Hu, Liu, Delbruck, CVPRW 2021) ``v2ecore/v2e_args.py``: ``pos_thres``,
  ``neg_thres`` 0.2, ``sigma_thres`` 0.03; ESIM (Rebecq et al., CoRL 2018):
  contrast thresholds 0.2 by default.

The nominal lenses (focal length in mm, giving ``fx = fy = f / pitch``) are a
convenience for 3-D scenes, not part of the sensors; the DAVIS240's
intrinsics are the Event Camera Dataset's calibration of its DAVIS240C.
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
        Where the documented figures come from, in short (see the module docstring).
    sources : tuple of (str, str)
        ``(field, where it comes from)`` for the resolution, pitch, thresholds,
        mismatch and refractory period; :meth:`source_of` reads it.
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
    sources: tuple[tuple[str, str], ...] = ()

    def source_of(self, field: str) -> str:
        """Where ``field``'s value comes from (``"typical: ..."`` for a typical value).

        Parameters
        ----------
        field : str
            A field name (``width``, ``pixel_pitch_um``, ``contrast_pos``, ...).

        Returns
        -------
        str

        Raises
        ------
        ValueError
            A field without a recorded source (the ones that have one are listed).

        Examples
        --------
        >>> sensor_model("gen4").source_of("pixel_pitch_um")
        'Finateu et al., ISSCC 2020 (title: 4.86 um pixels)'
        """
        for name, where in self.sources:
            if name == field:
                return where
        raise ValueError(f"sensor {self.name!r}: no recorded source for {field!r}; "
                         f"recorded: {[name for name, _ in self.sources]}")

    @property
    def event_params(self) -> dict[str, float]:
        """The pixel settings as :class:`evedge.sim.ConverterParams` keywords."""
        return dict(contrast_pos=self.contrast_pos, contrast_neg=self.contrast_neg,
                    contrast_sigma=self.contrast_sigma, refractory_us=self.refractory_us)


def _log(contrast: float) -> float:
    return round(math.log1p(contrast), 4)


_TYP_C = "typical: v2e's and ESIM's default threshold 0.2 (log units); the maker publishes no figure"
_TYP_SIGMA = "typical: v2e's default sigma_thres 0.03"
_TYP_REFR = "typical: 100 us (no maker publishes the refractory time at default biases; ESIM and v2e default to none)"


def _model(name, width, height, pitch_um, lens_mm, c_on, c_off, sigma, refractory_us, documented, source,
           sources, intrinsics=None):
    f = lens_mm * 1e3 / pitch_um
    fx, fy, cx, cy = intrinsics if intrinsics else (round(f, 3), round(f, 3), (width - 1) / 2, (height - 1) / 2)
    # the typical values' sources, unless the preset gives its own
    given = dict(sources)
    for key, where in (("contrast_pos", _TYP_C), ("contrast_neg", _TYP_C), ("contrast_sigma", _TYP_SIGMA),
                       ("refractory_us", _TYP_REFR)):
        given.setdefault(key, where)
    for key in ("width", "height"):
        given.setdefault(key, given["resolution"])
    given.pop("resolution")
    return SensorModel(name, width, height, pitch_um, fx, fy, cx, cy, _log(c_on), _log(c_off), sigma,
                       refractory_us, documented, source, tuple(sorted(given.items())))


_SIZE = ("width", "height", "pixel_pitch_um")
#: The contrast whose log step is v2e's and ESIM's 0.2: ln(1 + c) = 0.2.
_C02 = math.expm1(0.2)
_ROWS = "iniVation libcaer chip identifier"

#: The presets, by name.
SENSOR_MODELS: dict[str, SensorModel] = {m.name: m for m in (
    # 4.5 mm lens on 40 um pixels: fx = 112.5 (the previous dvs128 preset)
    _model("dvs128", 128, 128, 40.0, 4.5, 0.15, 0.15, round(math.log1p(0.021), 4), 100.0,
           _SIZE + ("contrast_sigma",), "Lichtsteiner et al., IEEE JSSC 2008; INI DVS128 user guide", {
               "resolution": "Lichtsteiner et al., IEEE JSSC 2008 (title: 128x128)",
               "pixel_pitch_um": "Lichtsteiner et al. 2008 (abstract: 40x40 um2 pixels); INI DVS128 user guide",
               "contrast_sigma": "Lichtsteiner et al. 2008 (abstract: 2.1 % threshold mismatch, 1 sigma)",
               "contrast_pos": "typical: 15 % contrast (the previous preset's value; not a maker's figure)",
               "contrast_neg": "typical: 15 % contrast (the previous preset's value; not a maker's figure)"}),
    _model("davis240", 240, 180, 18.5, 3.7, 0.11, 0.11, 0.03, 100.0,
           _SIZE + ("fx", "fy", "cx", "cy", "contrast_pos", "contrast_neg"),
           "Brandli et al., IEEE JSSC 2014; iniVation DAVIS240 specification; Event Camera Dataset calibration", {
               "resolution": f"Brandli et al., IEEE JSSC 2014 (title: 240x180); {_ROWS} DAVIS240A-C",
               "pixel_pitch_um": "Brandli et al. 2014: 18.5 um (not re-read here)",
               "contrast_pos": "iniVation DAVIS240 specification: 11 % contrast sensitivity (not re-read here)",
               "contrast_neg": "iniVation DAVIS240 specification: 11 % contrast sensitivity (not re-read here)"},
           intrinsics=(199.092, 198.829, 132.192, 110.713)),
    # f = 260 px (the previous davis346 preset): a 4.81 mm lens
    _model("davis346", 346, 260, 18.5, 4.81, 0.143, 0.225, 0.03, 100.0,
           _SIZE + ("contrast_pos", "contrast_neg"), "iniVation DAVIS346 specification; libcaer", {
               "resolution": f"{_ROWS} DAVIS346A-C ('346x260')",
               "pixel_pitch_um": "iniVation DAVIS346 specification: 18.5 um (not re-read here)",
               "contrast_pos": "iniVation DAVIS346 specification: 14.3 % ON at default biases (not re-read here)",
               "contrast_neg": "iniVation DAVIS346 specification: 22.5 % OFF at default biases (not re-read here)"},
           intrinsics=(260.0, 260.0, 172.5, 129.5)),
    _model("dvxplorer", 640, 480, 9.0, 4.0, _C02, _C02, 0.03, 100.0, _SIZE,
           "Son et al., ISSCC 2017 (the DVXplorer's Samsung DVS)", {
               "resolution": "Son et al., ISSCC 2017: '640x480 VGA-resolution DVS' (the DVXplorer's Samsung chip)",
               "pixel_pitch_um": "Son et al., ISSCC 2017: '9 um pixel pitch'",
               "contrast_pos": _TYP_C + " (iniVation documents bias presets, not a contrast)",
               "contrast_neg": _TYP_C + " (iniVation documents bias presets, not a contrast)"}),
    _model("gen3", 640, 480, 15.0, 8.0, _C02, _C02, 0.03, 100.0, _SIZE,
           "Prophesee Metavision documentation (Gen3.1 VGA); Gen3 VGA product brief", {
               "resolution": "Prophesee Metavision documentation: 'Gen3.1 VGA Sensor' (640x480)",
               "pixel_pitch_um": "Prophesee Gen3 VGA product brief: 15 um (not re-read here)",
               "contrast_pos": _TYP_C + " (Prophesee's datasheet figures need a customer login)",
               "contrast_neg": _TYP_C + " (Prophesee's datasheet figures need a customer login)"}),
    _model("gen4", 1280, 720, 4.86, 4.0, _C02, _C02, 0.03, 100.0, _SIZE, "Finateu et al., ISSCC 2020", {
               "resolution": "Finateu et al., ISSCC 2020 (title: 1280x720); Metavision documentation 'IMX636 HD'",
               "pixel_pitch_um": "Finateu et al., ISSCC 2020 (title: 4.86 um pixels)",
               "contrast_pos": _TYP_C + " (Prophesee's datasheet figures need a customer login)",
               "contrast_neg": _TYP_C + " (Prophesee's datasheet figures need a customer login)"}),
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
