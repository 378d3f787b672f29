"""The settings of a synthetic sequence, declared once: :data:`SYNTH_OPTIONS` and :class:`SynthConfig`.

Each setting is an :class:`~tracker.engine.registry.Option` (type, default, bounds, unit, help), as a tracking
run's are (:mod:`tracker.app.schema`). ``pose-tracker synth``'s flags, :func:`tracker.synthesize`'s keywords, an
experiment file's ``[[sequence]]`` keys and ``meta.json`` are derived from them: the option's name is the flag
(``--lighting-change``), the keyword and the key; :class:`SynthConfig` holds the checked values. The number of
cameras is named ``cameras`` everywhere a user writes it; :class:`SynthConfig` and ``meta.json`` keep it as
``views``, the name files written so far carry.

This module imports no renderer, so help texts and experiment files read it cheaply.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, fields
from typing import Any, Mapping

from data_tools.io.checks import MAX_FPS, MAX_IMAGE_SIDE, MAX_VIEWS, MIN_FPS
from tracker.core.errors import InputError
from tracker.engine.registry import Option

__all__ = ["SYNTH_OPTIONS", "SynthConfig", "synth_option", "FIELD_OF", "renamed_views"]

SYNTH_OPTIONS: tuple[Option, ...] = (
    Option("cameras", int, 4, "number of cameras", minimum=1, maximum=MAX_VIEWS),
    Option("fps", float, 60.0, "frame rate; the clip is resampled to it (60 is the rate train uses)",
           minimum=MIN_FPS, maximum=MAX_FPS, unit="Hz"),
    Option("start", int, 0, "first frame, at the output rate", minimum=0, unit="frames"),
    Option("frames", int, None, "number of frames (default: to the end)", minimum=1, unit="frames"),
    Option("seed", int, 0, "random seed: scene, clothing, widths, noise", minimum=0, maximum=2 ** 63 - 1),
    Option("width", int, 640, "image width", minimum=1, maximum=MAX_IMAGE_SIDE, unit="pixels"),
    Option("height", int, 480, "image height", minimum=1, maximum=MAX_IMAGE_SIDE, unit="pixels"),
    Option("noise", float, 2.0, "sensor noise std, in grey levels of 255", minimum=0.0, maximum=255.0),
    Option("lighting_change", float, 0.0, "the brightness drifts from 1 to 1 + this fraction over the sequence",
           minimum=-0.9, strict=True, maximum=2.0, strict_max=True),
    Option("occluder", bool, False, "a pillar between camera 0 and the person"),
    Option("missing_camera", int, None, "index of a camera that delivers only black frames", minimum=0),
    Option("turn", float, 0.0, "turn the whole clip about the vertical axis (counter-clockwise seen from above), "
           "so the person moves in another direction through the rig", minimum=-360.0, maximum=360.0,
           unit="degrees"),
)

#: The :class:`SynthConfig` field of each option whose field is named otherwise.
FIELD_OF: Mapping[str, str] = {"cameras": "views"}


def renamed_views(settings: Mapping[str, Any], owner: str) -> dict[str, Any]:
    """``settings`` with ``views``, the former name of ``cameras`` (a number of cameras: tracking's ``views`` are
    camera indices), renamed, and a deprecation warning naming ``owner``; both given is an :class:`InputError`."""
    settings = dict(settings)
    if "views" in settings:
        if "cameras" in settings:
            raise InputError("give the number of cameras once: cameras, not both cameras and views")
        logging.getLogger(__name__).warning(f"{owner}: views is deprecated and will be removed: use cameras (the "
                                            "number of cameras to render; tracking's views are camera indices)")
        settings["cameras"] = settings.pop("views")
    return settings


def synth_option(name: str) -> Option:
    """The declared synth setting ``name``."""
    return next(o for o in SYNTH_OPTIONS if o.name == name)


@dataclass(frozen=True)
class SynthConfig:
    """The settings of a synthetic sequence (all recorded in ``meta.json``), one field per option of
    :data:`SYNTH_OPTIONS` (``views``: the number of cameras, the option ``cameras``), each checked by its option
    on construction: a bad one is an :class:`InputError` naming it before anything is rendered.

    ``noise``: std of the Gaussian sensor noise, grey levels of 255. ``lighting_change``: the scene's brightness
    drifts linearly from 1 to ``1 + lighting_change`` over the sequence (the background plate is taken at 1).
    ``occluder``: a pillar stands between camera 0 and the capture area. ``missing_camera``: index of a camera
    that delivers only black frames (a dead camera; its plate is black too). ``turn``: the whole clip is turned
    by this many degrees about the vertical axis before it is placed (counter-clockwise seen from above), so
    one motion can be rendered walking in another direction through the same rig
    (:func:`data_tools.synthesis.synth.turned`).
    """

    views: int = synth_option("cameras").default
    fps: float = synth_option("fps").default
    start: int = synth_option("start").default
    frames: int | None = synth_option("frames").default
    seed: int = synth_option("seed").default
    width: int = synth_option("width").default
    height: int = synth_option("height").default
    noise: float = synth_option("noise").default
    lighting_change: float = synth_option("lighting_change").default
    occluder: bool = synth_option("occluder").default
    missing_camera: int | None = synth_option("missing_camera").default
    turn: float = synth_option("turn").default

    def __post_init__(self):
        for option in SYNTH_OPTIONS:
            name = FIELD_OF.get(option.name, option.name)
            value = getattr(self, name)
            if option.type is bool and not isinstance(value, bool):  # true or false, not a number
                raise InputError(f"synth setting: {option.name} must be true or false, got {value!r}")
            if value is None and option.default is not None:  # only the settings whose default is "none" take None
                raise InputError(f"synth setting: {option.name} must be given (default {option.default!r}), got None")
            object.__setattr__(self, name, option.parse(value, "synth setting"))

    @classmethod
    def of(cls, settings: Mapping[str, Any], owner: str = "synth setting") -> "SynthConfig":
        """The settings given by option name (``cameras``, ``lighting_change``, ...; the rest, and those given as
        None, default); an unknown name is an :class:`InputError` naming ``owner`` and the settings there are."""
        known = [o.name for o in SYNTH_OPTIONS]
        unknown = sorted(set(settings) - set(known))
        if unknown:
            raise InputError(f"unknown {owner} {', '.join(map(repr, unknown))} (the settings: {', '.join(known)})")
        return cls(**{FIELD_OF.get(k, k): v for k, v in settings.items() if v is not None})  # None: the default

    def as_options(self) -> dict[str, Any]:
        """The settings by option name (``cameras``, not ``views``)."""
        by_field = {v: k for k, v in FIELD_OF.items()}
        return {by_field.get(f.name, f.name): getattr(self, f.name) for f in fields(self)}

    def check_missing_camera(self, n_cameras: int, name: str = "missing camera") -> None:
        """An :class:`InputError` unless ``missing_camera`` (if any) is one of ``n_cameras`` rendered cameras; the
        message calls the setting ``name`` (as the user wrote it: an experiment file's key, say)."""
        if self.missing_camera is not None and self.missing_camera >= n_cameras:
            raise InputError(f"{name} {self.missing_camera} is not one of the {n_cameras} rendered cameras "
                             f"(0..{n_cameras - 1})")
