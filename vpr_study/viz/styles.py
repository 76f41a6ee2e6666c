"""What tells the runs of a figure apart: one colour per method in every figure (the paper's
methods fixed, peers and a user's methods from their own palette), a line style per weighting, a
marker per other setting, and legend labels that say what differs between the runs."""

from __future__ import annotations

import dataclasses
import zlib
from collections.abc import Sequence
from typing import Any

from matplotlib.colors import to_hex

from vpr_core import Matching, Method, available_methods, get_method

__all__ = [
    "DEFAULT_SETTINGS",
    "MARKERS",
    "METHOD_COLORS",
    "OTHER_COLORS",
    "SETTING_STYLES",
    "WEIGHTING_STYLES",
    "RunStyle",
    "method_color",
    "method_of",
    "run_labels",
    "run_styles",
    "settings_of",
]

#: The colour of each of the paper's methods (and ``global``), the same in every figure of the
#: study and the workbench. Grey is the chance level's.
METHOD_COLORS = {
    "dense": "tab:red",
    "classical": "tab:blue",
    "selection_scheme1": "tab:green",
    "selection_scheme2": "tab:orange",
    "overlap_scheme1": "tab:purple",
    "overlap_scheme2": "tab:brown",
    "global": "tab:pink",
}

#: The palette of peers (VPR-Bench techniques, a user's matrices) and a user's own methods: none of
#: :data:`METHOD_COLORS`. A name keeps its colour from figure to figure (picked by a hash of the
#: name; two names of one figure that pick the same colour: the later takes the next free one).
OTHER_COLORS = ("black", "tab:cyan", "tab:olive", "#00796b", "#1a237e")

#: Line style of each database weighting (not in the paper) in every figure; none: solid.
WEIGHTING_STYLES: dict[str, Any] = {
    "": "-",
    "contrast": (0, (6, 2)),
    "idf": (0, (1, 1.5)),
    "two_sided": (0, (6, 2, 1, 2)),
}
_EXTRA_STYLES = ((0, (3, 1, 1, 1)), (0, (8, 2, 1, 2, 1, 2)), (0, (2, 3)), (0, (10, 3)))

#: Line styles of the other settings in a figure whose runs share one weighting (the line style
#: is free there): with the marker, they tell apart the runs of one method that cross each other
#: (a parameter sweep: IoU 0.4 ... 0.7, Tables 2-4's sets).
SETTING_STYLES = (
    (0, (4, 1.5)),
    (0, (8, 2, 2, 2)),
    (0, (1, 2)),
    (0, (10, 3)),
    (0, (3, 1, 1, 1, 1, 1)),
)

#: Markers of the other settings (scheme options, backbone, normalisation, geometry, pooling, a
#: shortlist...), in the order a figure meets them; a run at the defaults has none.
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*", "<", ">", "h", "p")

#: The run settings a label or a title names only when they differ from these.
DEFAULT_SETTINGS = {"backbone": "efficientnet_lite0", "pooling": "crop"}

#: The settings that make a run's line style (the weighting) and colour (the method); every
#: other setting of :func:`settings_of` makes its marker.
_STYLE_KEYS = ("method", "weighting")


@dataclasses.dataclass(frozen=True)
class RunStyle:
    """How one run of a figure is drawn: ``color``, ``linestyle``, ``marker`` (None: none) and
    its legend ``label``."""

    color: Any
    linestyle: Any
    marker: str | None
    label: str

    def line(self) -> dict[str, Any]:
        """Keyword arguments of ``ax.plot`` for this run (markers spread along the line)."""
        return {"color": self.color, "ls": self.linestyle, "marker": self.marker or "None"}


def method_of(run: Any) -> str:
    """A run's method name (``run.method``); a result without one: its label up to ``" ("``."""
    method = getattr(run, "method", None)
    return str(method) if method else str(run.label).split(" (", 1)[0]


def method_color(method: str, taken: Sequence[Any] = ()) -> Any:
    """The colour of ``method`` in every figure: :data:`METHOD_COLORS` for the paper's methods,
    else one of :data:`OTHER_COLORS` picked by the name (crc32), the next one not in ``taken``
    (colours other methods of the figure hold) when that one is."""
    if method in METHOD_COLORS:
        return METHOD_COLORS[method]
    start = zlib.crc32(method.encode("utf-8")) % len(OTHER_COLORS)
    order = OTHER_COLORS[start:] + OTHER_COLORS[:start]
    used = {to_hex(c) for c in taken}
    return next((c for c in order if to_hex(c) not in used), order[0])


def _text(value: Any) -> str:
    if isinstance(value, tuple):
        return "/".join(_text(v) for v in value)
    return f"{value:g}" if isinstance(value, float) else str(value)


def _preset(config: Any) -> Any:
    """The method a configuration's options are told against: the preset of its name, else
    its scheme's class at its defaults with plain matching (None: no defaults to tell)."""
    if config.name in available_methods():
        return get_method(config.name)
    try:
        return dataclasses.replace(config, landmarks=type(config.landmarks)(), matching=Matching())
    except (TypeError, ValueError):
        return None


def _options(config: Any) -> str:
    """The scheme and matching options of a :class:`~vpr_core.Method` that differ from its
    preset's (:func:`_preset`), the weighting aside: ``"iou_threshold=0.4"``, ``""``."""
    preset = _preset(config)
    out = []
    for part in ("landmarks", "matching"):
        value, base = getattr(config, part), getattr(preset, part, None)
        same_type = base is not None and type(base) is type(value)
        for f in dataclasses.fields(value):
            v = getattr(value, f.name)
            if f.name != "weighting" and (not same_type or v != getattr(base, f.name)):
                out.append(f"{f.name}={_text(v)}")
    return ", ".join(out)


def settings_of(run: Any) -> dict[str, str]:
    """Everything a run is made of that a figure may vary, as text (unset or the preset's:
    ``""``): ``method``, ``weighting``, ``options`` (the other scheme and matching options that
    differ from the method's preset), ``normalised`` (a peer's), ``backbone``, ``weights``,
    ``pooling``, ``input size``, ``shortlist``."""
    config = getattr(run, "config", None)
    matching = getattr(config, "matching", None)
    out = {"method": method_of(run), "weighting": "", "options": "", "normalised": ""}
    if isinstance(config, Method):
        out["weighting"] = str(config.matching.weighting or "")
        out["options"] = _options(config)
    elif isinstance(config, dict):  # a peer's record
        out["normalised"] = str(config.get("normalise") or "")
    elif matching is not None:  # a result-like value of another kind
        out["weighting"] = str(getattr(matching, "weighting", None) or "")
    encoder = getattr(run, "encoder", None)
    encoder = encoder if isinstance(encoder, dict) else {}
    for key in ("backbone", "pooling", "input_size"):
        value = encoder.get(key)
        out[key.replace("_", " ")] = "" if value is None else str(value)
    out["weights"] = str(encoder.get("weights_sha256") or "")[:8]
    shortlist = getattr(run, "shortlist", None)
    out["shortlist"] = "" if shortlist is None else f"k={shortlist}"
    return out


#: The settings a default label (``run_method``'s) does not say, as the legend adds them when
#: they differ between the runs of a figure: ``(setting, words before the value)``.
_UNSAID = (
    ("backbone", "backbone: "),
    ("weights", "weights "),
    ("pooling", "pooling "),
    ("input size", "crop "),
    ("shortlist", "shortlist "),
)


def _with(label: str, extra: list[str]) -> str:
    """``label`` with ``extra`` inside its last parenthesis (``dense (weighting: contrast;
    backbone: TinyNet)``), or in a new one."""
    if not extra:
        return label
    if label.endswith(")") and " (" in label:
        return f"{label[:-1]}; {'; '.join(extra)})"
    return f"{label} ({'; '.join(extra)})"


def run_labels(results: Sequence[Any]) -> list[str]:
    """The legend label of each run: its label, then each setting that differs between the runs
    and the label does not already say (backbone, pooling, shortlist; weights and crop size
    among the runs of one backbone; a default value is not said); labels still alike get their
    run keys (the scheme and matching options), then a number.

    Args:
        results: the runs of one figure (``.label``; ``.config``, ``.encoder``, ``.shortlist``
            where known).
    """
    settings = [settings_of(r) for r in results]
    labels = []
    for r, s in zip(results, settings, strict=True):
        extra = []
        for key, words in _UNSAID:
            # weights and crop size: among the runs of one backbone (another has its own)
            own = key in ("weights", "input size")
            peers = [t for t in settings if not own or t["backbone"] == s["backbone"]]
            values = {t[key] for t in peers}
            value = s[key]
            if len(values) < 2 or not value or value == DEFAULT_SETTINGS.get(key):
                continue
            if value.lower() not in str(r.label).lower():
                extra.append(f"{words}{value}")
        labels.append(_with(str(r.label), extra))
    for label in sorted(set(labels)):  # a label given twice: its run key says what differs
        if labels.count(label) > 1:
            twins = [j for j, other in enumerate(labels) if other == label]
            keys = [str(getattr(results[j], "run", "") or "") for j in twins]
            if len(set(keys)) == len(keys):
                for j, key in zip(twins, keys, strict=True):
                    labels[j] = _with(labels[j], [key])
    seen: dict[str, int] = {}
    for i, label in enumerate(labels):
        seen[label] = seen.get(label, 0) + 1
        if seen[label] > 1:
            labels[i] = f"{label} #{seen[label]}"
    return labels


#: The encoder's settings: a run without them (a peer) has none to tell, not an unset one.
_ENCODER_KEYS = ("backbone", "pooling", "input size", "weights")


def _baseline(settings: list[dict[str, str]]) -> dict[str, str]:
    """Per setting, the value a figure draws without a marker: the default (the CLI's, else
    unset) where a run has it, else the first run's (of an encoder's setting: the first run's
    that has an encoder)."""
    out = {}
    for key in settings[0] if settings else ():
        values = [s[key] for s in settings]
        if key in _ENCODER_KEYS:
            values = [v for v in values if v] or [""]
        default = DEFAULT_SETTINGS.get(key, "")
        out[key] = default if default in values else values[0]
    return out


def _plain(key: tuple, base: dict[str, str]) -> bool:
    """A run's other settings (``(setting, value)`` pairs) are all the figure's baseline (a
    peer's missing encoder settings included)."""
    return all(v == base[k] or (k in _ENCODER_KEYS and not v) for k, v in key)


def run_styles(results: Sequence[Any], colors: dict | None = None) -> list[RunStyle]:
    """Colour, line style, marker and legend label of each run of one figure: colour by method
    (:func:`method_color`; ``colors`` ``{label: colour}`` wins), line style by weighting
    (:data:`WEIGHTING_STYLES`), marker by every other setting (:func:`settings_of`: no marker
    at the defaults, then :data:`MARKERS` in the order the figure meets them) and, where all the
    runs share one weighting, also line style (:data:`SETTING_STYLES`). Two runs never
    share all three: a run that would (two labels of one configuration, a setting this does not
    know) takes the next marker free for its colour and style.

    Args:
        results: the runs of one figure, in drawing order.
        colors: ``{label: colour}`` chosen by the caller.
    """
    colors = dict(colors or {})
    settings = [settings_of(r) for r in results]
    labels = run_labels(results)
    by_method: dict[str, Any] = {}
    for r, s in zip(results, settings, strict=True):
        method = s["method"]
        if method not in by_method and r.label not in colors:
            by_method[method] = method_color(method, list(by_method.values()))
    extra = iter(_EXTRA_STYLES)
    line_of: dict[str, Any] = {}
    for s in settings:
        w = s["weighting"]
        if w not in line_of:
            line_of[w] = WEIGHTING_STYLES.get(w) or next(extra, "-.")
    rest = [tuple((k, v) for k, v in s.items() if k not in _STYLE_KEYS) for s in settings]
    base = _baseline(settings)
    marker_of: dict[tuple, str | None] = {}
    for key in rest:
        if key not in marker_of:
            free = [m for m in MARKERS if m not in marker_of.values()]
            marker_of[key] = None if _plain(key, base) else (free or list(MARKERS))[0]
    out: list[RunStyle] = []
    seen: set[tuple] = set()
    for r, s, key, label in zip(results, settings, rest, labels, strict=True):
        color = colors.get(r.label) or by_method[s["method"]]
        marker = marker_of[key]
        style = line_of[s["weighting"]]
        if len(line_of) == 1 and marker is not None:  # the line style is free: the settings'
            rank = [m for m in dict.fromkeys(marker_of.values()) if m is not None].index(marker)
            style = SETTING_STYLES[rank % len(SETTING_STYLES)]
        ident = (to_hex(color), str(style), marker)
        if ident in seen:  # never two runs drawn alike
            marker = next(
                (m for m in MARKERS if (ident[0], ident[1], m) not in seen), marker or "o"
            )
            ident = (ident[0], ident[1], marker)
        seen.add(ident)
        out.append(RunStyle(color, style, marker, label))
    return out
