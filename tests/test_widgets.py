"""flowtrack_course.widgets: sliders with a widget frontend, the static sweep figure without (headless)."""

import math
import types

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from flowtrack_course import widgets
from flowtrack_course.widgets import Choice, Slider, interactive_or_static, widget_frontend_available

X = np.linspace(0.0, 1.0, 4)


def line(ax, a=1.0, b=0.0, kind="lin"):
    y = a * X + b if kind == "lin" else a * X**2 + b
    ax.plot(X, y)
    ax.set_title(f"{a} {b} {kind}")
    return (a, b, kind)


@pytest.fixture(autouse=True)
def _close_figures(monkeypatch):
    monkeypatch.delenv("FLOWTRACK_WIDGETS", raising=False)
    monkeypatch.delenv("JPY_SESSION_NAME", raising=False)
    yield
    plt.close("all")


def test_headless_auto_mode_draws_the_one_at_a_time_sweep():
    out = interactive_or_static(
        line,
        a=Slider(1.0, 0.5, 2.0, static=(0.5, 1.0, 2.0)),
        b=Slider(0.0, -1.0, 1.0, static=(-1.0, 1.0)),
        kind=Choice(("lin", "quad")),
        show=False,
    )
    assert out.mode == "static" and out.widget is None
    expected = [
        (0.5, 0.0, "lin"), (1.0, 0.0, "lin"), (2.0, 0.0, "lin"),
        (1.0, -1.0, "lin"), (1.0, 1.0, "lin"),
        (1.0, 0.0, "lin"), (1.0, 0.0, "quad"),
    ]
    assert [r for _, r in out.calls] == expected
    assert [tuple(v.values()) for v, _ in out.calls] == expected
    axes = np.array(out.figure.axes).reshape(3, 3)  # one row per parameter, 3 columns
    drawn = [ax for ax in axes.ravel() if ax.axison]
    assert len(drawn) == 7 and not axes[1, 2].axison and not axes[2, 2].axison
    # each panel holds exactly the curve fn drew for its values (an independent recomputation)
    for ax, (a, b, kind) in zip(drawn, expected):
        (ln,) = ax.get_lines()
        want = a * X + b if kind == "lin" else a * X**2 + b
        np.testing.assert_allclose(ln.get_ydata(), want)
    assert repr(out) == "InteractiveResult(mode='static', panels=7)"


def test_default_static_values_are_min_default_max_and_single_values_give_one_panel():
    s = Slider(1.0, 0.01, 100.0, log=True)
    assert s.static == (0.01, 1.0, 100.0)
    assert Slider(0.0, 0.0, 1.0).static == (0.0, 1.0)  # duplicates removed
    out = interactive_or_static(line, a=Slider(2.0, 1.0, 3.0, static=(2.0,)), show=False, title="t")
    assert [r for _, r in out.calls] == [(2.0, 0.0, "lin")]
    assert out.figure._suptitle.get_text() == "t"


def test_integer_slider_passes_ints():
    seen = []
    interactive_or_static(lambda ax, n=1: seen.append(n), n=Slider(3, 1, 5, integer=True), show=False)
    assert seen == [1, 3, 5] and all(type(v) is int for v in seen)
    with pytest.raises(ValueError, match="integral"):
        Slider(2.5, 1, 5, integer=True)


def test_widget_mode_builds_sliders_that_call_fn():
    ipywidgets = pytest.importorskip("ipywidgets")
    seen = []

    def fn(ax, lam=1.0, kind="a"):
        seen.append((lam, kind))

    out = interactive_or_static(
        fn, mode="widgets", show=False,
        lam=Slider(0.1, 1e-3, 10.0, log=True, description="λ"),
        kind=Choice(("a", "b"), value="b"),
    )
    assert out.mode == "widgets" and out.calls == [] and out.figure is None
    w = out.widget
    assert isinstance(w, ipywidgets.interactive)
    slider, drop = w.children[0], w.children[1]
    assert isinstance(slider, ipywidgets.FloatLogSlider) and isinstance(drop, ipywidgets.Dropdown)
    assert slider.description == "λ" and drop.description == "kind"
    assert math.isclose(slider.min, -3.0) and math.isclose(slider.max, 1.0) and slider.base == 10
    assert math.isclose(slider.value, 0.1) and drop.value == "b" and list(drop.options) == ["a", "b"]
    assert slider.continuous_update is False
    n0 = len(seen)
    slider.value = 2.0
    drop.value = "a"
    assert seen[n0:] == [(2.0, "b"), (2.0, "a")]  # every change redraws with the new values


def test_linear_and_integer_widgets():
    ipywidgets = pytest.importorskip("ipywidgets")
    out = interactive_or_static(
        lambda ax, a=0.0, n=1: None, mode="widgets", show=False,
        a=Slider(0.0, -2.0, 2.0), n=Slider(2, 1, 4, integer=True),
    )
    a, n = out.widget.children[:2]
    assert isinstance(a, ipywidgets.FloatSlider) and isinstance(n, ipywidgets.IntSlider)
    assert math.isclose(a.step, 0.1) and (n.min, n.max, n.value) == (1, 4, 2)


class _Shell:
    kernel = object()


def test_frontend_detection(monkeypatch):
    pytest.importorskip("ipywidgets")
    import IPython

    assert widget_frontend_available() is False  # pytest: no kernel
    monkeypatch.setenv("FLOWTRACK_WIDGETS", "widgets")
    assert widget_frontend_available() is False  # forcing widgets still needs a kernel
    monkeypatch.setattr(IPython, "get_ipython", lambda: _Shell())
    assert widget_frontend_available() is True
    monkeypatch.delenv("FLOWTRACK_WIDGETS")
    assert widget_frontend_available() is False  # a kernel alone (nbclient) is headless
    monkeypatch.setenv("JPY_SESSION_NAME", "/work/lesson.ipynb")  # set by Jupyter Server
    assert widget_frontend_available() is True
    monkeypatch.setenv("FLOWTRACK_WIDGETS", "static")
    assert widget_frontend_available() is False
    monkeypatch.setattr(IPython, "get_ipython", lambda: types.SimpleNamespace())  # terminal IPython
    monkeypatch.setenv("FLOWTRACK_WIDGETS", "")
    assert widget_frontend_available() is False


def test_auto_mode_follows_the_detection(monkeypatch):
    pytest.importorskip("ipywidgets")
    monkeypatch.setattr(widgets, "widget_frontend_available", lambda: True)
    out = interactive_or_static(line, a=Slider(1.0, 0.0, 2.0), show=False)
    assert out.mode == "widgets"
    out = interactive_or_static(line, a=Slider(1.0, 0.0, 2.0), show=False, mode="static")
    assert out.mode == "static"


@pytest.mark.parametrize(
    "kwargs, err, match",
    [
        ({"value": 1.0, "min": 2.0, "max": 1.0}, ValueError, "min must be < max"),
        ({"value": 3.0, "min": 0.0, "max": 1.0}, ValueError, "value must be in"),
        ({"value": 1.0, "min": 0.0, "max": 2.0, "log": True}, ValueError, "min must be > 0"),
        ({"value": 1.0, "min": 0.0, "max": 2.0, "static": (0.0, 5.0)}, ValueError, "static values"),
        ({"value": 1.0, "min": 0.0, "max": 2.0, "static": ()}, ValueError, "static"),
        ({"value": 1.0, "min": 0.0, "max": 2.0, "step": 0.0}, ValueError, "step"),
        ({"value": "1", "min": 0.0, "max": 2.0}, TypeError, "value"),
        ({"value": 1.0, "min": float("nan"), "max": 2.0}, ValueError, "min"),
    ],
)
def test_slider_bad_input(kwargs, err, match):
    with pytest.raises(err, match=match):
        Slider(**kwargs)


def test_choice_bad_input():
    with pytest.raises(ValueError, match="value must be one of"):
        Choice(("a", "b"), value="c")
    with pytest.raises(ValueError, match="options"):
        Choice(())
    with pytest.raises(TypeError, match="options"):
        Choice("ab")
    with pytest.raises(ValueError, match="static"):
        Choice(("a", "b"), static=("z",))


def test_interactive_or_static_bad_input():
    s = Slider(1.0, 0.0, 2.0)
    with pytest.raises(TypeError, match="fn must be callable"):
        interactive_or_static(42, a=s, show=False)
    with pytest.raises(TypeError, match="fn must accept"):
        interactive_or_static(lambda ax, a: None, b=s, show=False)
    with pytest.raises(TypeError, match=r"a must be a flowtrack_course\.widgets\.Slider"):
        interactive_or_static(line, a=(0.0, 1.0), show=False)
    with pytest.raises(ValueError, match="mode"):
        interactive_or_static(line, a=s, mode="browser", show=False)
    with pytest.raises(ValueError, match="params"):
        interactive_or_static(line, show=False)
    with pytest.raises(ValueError, match="panel_size"):
        interactive_or_static(line, a=s, panel_size=(4.0, -1.0), show=False)
