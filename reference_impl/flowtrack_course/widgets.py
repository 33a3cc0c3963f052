r"""Sliders where a widget frontend exists, a static figure everywhere else (lessons' tuning cells).

A lesson cell that lets the reader tune a parameter (the smoothness weight :math:`\lambda` of scene
flow, the noise variances :math:`q, r` of a Kalman filter) is written once as a drawing function
``fn(ax, **params)`` and handed to :func:`interactive_or_static`:

* in a live Jupyter kernel with a widget frontend, ``ipywidgets.interactive`` puts one slider (or
  drop-down) per parameter under a plot that ``fn`` redraws on every change;
* everywhere else — a headless ``nbclient`` run, the test suite, the static book, plain Python — the
  same ``fn`` is called for a few values of each parameter, one parameter at a time with the others
  at their defaults, and the panels are laid out in one figure: row :math:`r` varies the
  :math:`r`-th parameter over its ``static`` values.

Whether a widget frontend is present cannot be asked of the kernel (widgets render in the browser,
the kernel only opens comms), so :func:`widget_frontend_available` decides from the environment:
a kernel started by Jupyter Server for an open notebook has ``JPY_SESSION_NAME`` set (JupyterLab,
Notebook 7, Voilà), Google Colab is recognised by its module; ``nbclient``/``jupyter-book``
executions have neither. The environment variable ``FLOWTRACK_WIDGETS`` overrides the guess:
``static`` (or ``0``/``off``) always draws the static figure, ``widgets`` (or ``1``/``on``) always
builds sliders inside a kernel.

Examples
--------
>>> import matplotlib
>>> matplotlib.use("Agg")
>>> def parabola(ax, a=1.0, shift=0.0):
...     x = np.linspace(-1, 1, 5)
...     ax.plot(x, a * x**2 + shift)
...     return float(a + shift)
>>> out = interactive_or_static(parabola, a=Slider(1.0, 0.1, 10.0, log=True),
...                             shift=Slider(0.0, -1.0, 1.0, static=(-1.0, 1.0)), show=False)
>>> out.mode, len(out.calls)
('static', 5)
>>> [(c["a"], c["shift"]) for c, _ in out.calls]
[(0.1, 0.0), (1.0, 0.0), (10.0, 0.0), (1.0, -1.0), (1.0, 1.0)]
>>> [r for _, r in out.calls]
[0.1, 1.0, 10.0, 0.0, 2.0]
"""

from __future__ import annotations

import inspect
import math
import os
import sys
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from flowtrack.validation import scalar

__all__ = ["Choice", "InteractiveResult", "Slider", "interactive_or_static", "widget_frontend_available"]

_MODES = ("auto", "static", "widgets")
_ENV = "FLOWTRACK_WIDGETS"
_ENV_STATIC = ("0", "off", "no", "false", "static")
_ENV_WIDGETS = ("1", "on", "yes", "true", "widgets")


@dataclass(frozen=True)
class Slider:
    r"""A numeric parameter: slider range, default and the values of the static figure.

    Parameters
    ----------
    value : float
        Default (initial slider position; the value used while another parameter is swept).
    min, max : float
        Slider range, ``min < max``; with ``log=True`` both must be > 0.
    log : bool
        Logarithmic slider (``FloatLogSlider``, base 10) — for scale parameters like
        :math:`\lambda`, :math:`q`, :math:`r`.
    step : float, optional
        Slider step (in decades for ``log=True``); default 1/40 of the range (0.1 decade for log).
    static : tuple of float, optional
        Values drawn in the static figure, each in ``[min, max]``; default ``(min, value, max)``
        (duplicates removed).
    description : str, optional
        Slider label; default the parameter's name.
    integer : bool
        Integer parameter (``IntSlider``); ``value``, ``min``, ``max`` and ``static`` must be
        integral, and ``fn`` receives ints.

    Raises
    ------
    ValueError, TypeError
        Non-finite or non-numeric bounds, ``min >= max``, ``value`` or a ``static`` value outside
        ``[min, max]``, ``log`` with ``min <= 0``, non-positive ``step``.
    """

    value: float
    min: float
    max: float
    log: bool = False
    step: float | None = None
    static: tuple | None = None
    description: str | None = None
    integer: bool = False

    def __post_init__(self):
        lo, hi = scalar(self.min, "min"), scalar(self.max, "max")
        v = scalar(self.value, "value")
        if not lo < hi:
            raise ValueError(f"min must be < max, got min={lo}, max={hi}")
        if not lo <= v <= hi:
            raise ValueError(f"value must be in [min, max] = [{lo}, {hi}], got {v}")
        if self.log and lo <= 0:
            raise ValueError(f"min must be > 0 for a log slider, got {lo}")
        if self.step is not None and scalar(self.step, "step") <= 0:
            raise ValueError(f"step must be > 0, got {self.step}")
        static = (lo, v, hi) if self.static is None else tuple(self.static)
        if len(static) == 0:
            raise ValueError("static must hold at least one value")
        for s in static:
            s = scalar(s, "static values")
            if not lo <= s <= hi:
                raise ValueError(f"static values must be in [min, max] = [{lo}, {hi}], got {s}")
        if self.integer:
            for name, x in (("value", v), ("min", lo), ("max", hi), *(("static values", s) for s in static)):
                if float(x) != int(x):
                    raise ValueError(f"{name} must be integral for integer=True, got {x}")
            static = tuple(dict.fromkeys(int(s) for s in static))
        else:
            static = tuple(dict.fromkeys(float(s) for s in static))
        object.__setattr__(self, "static", static)

    @property
    def default(self):
        return int(self.value) if self.integer else float(self.value)

    def widget(self, name: str):
        """The ipywidgets control (``continuous_update=False``: ``fn`` runs when the slider is released)."""
        import ipywidgets as w

        label = self.description or name
        if self.integer:
            step = 1 if self.step is None else max(1, int(self.step))
            return w.IntSlider(value=int(self.value), min=int(self.min), max=int(self.max), step=step,
                               description=label, continuous_update=False)
        if self.log:
            return w.FloatLogSlider(value=float(self.value), base=10, min=math.log10(self.min),
                                    max=math.log10(self.max), step=0.1 if self.step is None else self.step,
                                    description=label, continuous_update=False)
        step = (self.max - self.min) / 40 if self.step is None else self.step
        return w.FloatSlider(value=float(self.value), min=float(self.min), max=float(self.max), step=step,
                             description=label, continuous_update=False)


@dataclass(frozen=True)
class Choice:
    """A categorical parameter: a drop-down in the widget view, one panel per option statically.

    Parameters
    ----------
    options : sequence
        The choices (at least one, no duplicates).
    value : optional
        Default, one of ``options``; default the first option.
    static : sequence, optional
        Options drawn in the static figure; default all of them.
    description : str, optional
        Label; default the parameter's name.
    """

    options: tuple
    value: Any = None
    static: tuple | None = None
    description: str | None = None

    def __post_init__(self):
        if isinstance(self.options, (str, bytes)):
            raise TypeError(f"options must be a sequence of choices, got the string {self.options!r}")
        opts = tuple(self.options)
        if not opts:
            raise ValueError("options must hold at least one choice")
        if len(set(map(repr, opts))) != len(opts):
            raise ValueError(f"options must not repeat, got {opts}")
        value = opts[0] if self.value is None else self.value
        if value not in opts:
            raise ValueError(f"value must be one of {opts}, got {value!r}")
        static = opts if self.static is None else tuple(self.static)
        bad = [s for s in static if s not in opts]
        if bad or not static:
            raise ValueError(f"static must be a non-empty subset of {opts}, got {static}")
        object.__setattr__(self, "options", opts)
        object.__setattr__(self, "value", value)
        object.__setattr__(self, "static", static)

    @property
    def default(self):
        return self.value

    def widget(self, name: str):
        import ipywidgets as w

        return w.Dropdown(options=list(self.options), value=self.value, description=self.description or name)


@dataclass
class InteractiveResult:
    """What :func:`interactive_or_static` did.

    Attributes
    ----------
    mode : {"static", "widgets"}
    calls : list of (dict, object)
        Static mode: the parameters of every panel, in drawing order, and what ``fn`` returned.
        Widget mode: empty (``fn`` runs later, on slider changes).
    figure : matplotlib.figure.Figure or None
        The static figure (static mode).
    widget : ipywidgets.interactive or None
        The controls and output (widget mode).
    """

    mode: str
    calls: list = field(default_factory=list)
    figure: Any = None
    widget: Any = None

    def __repr__(self) -> str:  # short: a notebook cell ending in the call prints this
        return f"InteractiveResult(mode={self.mode!r}, panels={len(self.calls)})"


def widget_frontend_available() -> bool:
    """Guess whether widgets will be rendered: an IPython kernel, ipywidgets, and a live frontend.

    True when ipywidgets imports, the code runs in an IPython *kernel* (not a terminal IPython or
    plain Python) and either ``FLOWTRACK_WIDGETS`` is ``widgets``/``1``/``on`` or the kernel was
    started for a notebook open in Jupyter Server (``JPY_SESSION_NAME``) or in Google Colab.
    ``FLOWTRACK_WIDGETS=static`` (or ``0``/``off``) makes it False. Headless runs (nbclient,
    jupyter-book, pytest) give False.

    Examples
    --------
    >>> widget_frontend_available()   # doctests run outside a kernel
    False
    """
    env = os.environ.get(_ENV, "").strip().lower()
    if env in _ENV_STATIC:
        return False
    try:
        import ipywidgets  # noqa: F401
        from IPython import get_ipython
    except ImportError:
        return False
    shell = get_ipython()
    if shell is None or getattr(shell, "kernel", None) is None:
        return False
    if env in _ENV_WIDGETS:
        return True
    return bool(os.environ.get("JPY_SESSION_NAME")) or "google.colab" in sys.modules


def _check_fn(fn, names) -> None:
    if not callable(fn):
        raise TypeError(f"fn must be callable as fn(ax, **params), got {type(fn).__name__}")
    try:
        sig = inspect.signature(fn)
    except (TypeError, ValueError):  # builtins without a signature: trust the caller
        return
    try:
        sig.bind(None, **{n: None for n in names})
    except TypeError as exc:
        raise TypeError(
            f"fn must accept fn(ax, {', '.join(f'{n}=...' for n in names)}): {exc}"
        ) from None


def interactive_or_static(
    fn,
    *,
    mode: str = "auto",
    title: str | None = None,
    panel_size: tuple[float, float] = (4.0, 3.0),
    show: bool = True,
    **params,
) -> InteractiveResult:
    r"""Show ``fn`` with sliders when a widget frontend is present, else as a static sweep figure.

    Parameters
    ----------
    fn : callable
        ``fn(ax, **values)`` draws one panel into the matplotlib axes ``ax`` for one value of every
        parameter; it may return something (a score), which static mode collects in ``calls``.
    mode : {"auto", "static", "widgets"}
        ``"auto"`` asks :func:`widget_frontend_available`; ``"widgets"`` forces sliders (needs
        ipywidgets), ``"static"`` forces the figure.
    title : str, optional
        Figure title (static mode) or the label above the widget.
    panel_size : (float, float)
        Width and height in inches of one panel.
    show : bool
        Display the figure or widget (``plt.show()`` / ``IPython.display``); pass False to only
        build and return it.
    **params : Slider or Choice
        One entry per keyword parameter of ``fn``.

    Returns
    -------
    InteractiveResult
        ``mode``, ``calls`` (static: ``[(values dict, fn's return), ...]`` row by row), ``figure``
        (static) or ``widget`` (an ``ipywidgets.interactive``).

    Notes
    -----
    The static figure has one row per parameter whose ``static`` tuple has more than one value
    (a single row with the defaults if none has), with :math:`\max_p |\text{static}_p|` columns:
    row :math:`r` holds ``fn`` at the defaults except for parameter :math:`r`, which takes its
    static values in order. That is the "one factor at a time" view of the sliders, and costs
    :math:`\sum_p |\text{static}_p|` calls of ``fn``.

    Raises
    ------
    TypeError
        ``fn`` not callable or not accepting ``(ax, **params)``; a parameter that is not a
        :class:`Slider` or :class:`Choice`.
    ValueError
        No parameters, unknown ``mode``, bad ``panel_size``.
    """
    if mode not in _MODES:
        raise ValueError(f"mode must be one of {_MODES}, got {mode!r}")
    if not params:
        raise ValueError("params: give at least one Slider or Choice as a keyword argument")
    for name, p in params.items():
        if not isinstance(p, (Slider, Choice)):
            raise TypeError(
                f"{name} must be a flowtrack_course.widgets.Slider or Choice, got {type(p).__name__}"
            )
    _check_fn(fn, list(params))
    size = np.asarray(panel_size, dtype=float) if not isinstance(panel_size, str) else np.zeros(0)
    if size.shape != (2,) or not np.all(np.isfinite(size)) or not np.all(size > 0):
        raise ValueError(f"panel_size must be (width, height) in inches, both > 0, got {panel_size!r}")

    use_widgets = mode == "widgets" or (mode == "auto" and widget_frontend_available())
    if use_widgets:
        return _widgets(fn, params, title, tuple(size), show)
    return _static(fn, params, title, tuple(size), show)


def _static(fn, params, title, size, show) -> InteractiveResult:
    import matplotlib.pyplot as plt

    defaults = {n: p.default for n, p in params.items()}
    rows = [(n, p.static) for n, p in params.items() if len(p.static) > 1]
    if not rows:
        rows = [(None, (None,))]
    ncols = max(len(vals) for _, vals in rows)
    fig, axes = plt.subplots(len(rows), ncols, figsize=(size[0] * ncols, size[1] * len(rows)), squeeze=False)
    calls = []
    for r, (name, vals) in enumerate(rows):
        for c in range(ncols):
            ax = axes[r, c]
            if c >= len(vals):
                ax.axis("off")
                continue
            values = dict(defaults)
            if name is not None:
                values[name] = vals[c]
            calls.append((values, fn(ax, **values)))
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    if show:
        plt.show()
    return InteractiveResult("static", calls, figure=fig)


def _widgets(fn, params, title, size, show) -> InteractiveResult:
    import ipywidgets as w
    import matplotlib.pyplot as plt

    def draw(**values):
        fig, ax = plt.subplots(figsize=size)
        fn(ax, **values)
        if title:
            fig.suptitle(title)
        fig.tight_layout()
        plt.show()

    controls = w.interactive(draw, **{n: p.widget(n) for n, p in params.items()})
    if show:
        from IPython.display import display

        display(controls)
    return InteractiveResult("widgets", widget=controls)
