"""The shared figure style: every axis labelled, the style in force for what is drawn later."""
import pytest

from pfbench import plotting


def test_label_refuses_an_unlabelled_axis():
    fig, ax = plotting.subplots()
    with pytest.raises(ValueError, match="label"):
        plotting.label(ax, "time [s]", " ")
    plotting.label(ax, "time [s]", "error [degC]", "title")
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("time [s]", "error [degC]")


def test_style_applies_to_what_is_drawn_after_subplots():
    """Catches the style applied only while the axes are made (a legend added later came out in
    matplotlib's default size)."""
    fig, ax = plotting.subplots()
    ax.plot([0, 1], [0, 1], label="ours")
    plotting.paper_value(ax, 0.5)
    leg = ax.legend()
    assert leg.get_texts()[0].get_fontsize() == plotting.STYLE["legend.fontsize"]
    assert [t.get_text() for t in leg.get_texts()] == ["ours", "paper"]
