"""The diagnosis report's ranking figure (issue 26): its title and colour key lie inside the
figure (the title used to run past the right edge)."""
from bayesdrag.plots.diagnosis import plot_ranking


def test_ranking_title_and_key_are_inside_the_figure():
    names = ["wind", "temperature", "density", "radar_time", "coriolis", "yaw_drag", "lift", "drag_scale"]
    s = {"effects": [{"name": n, "shrink": 0.9 - 0.1 * i, "significant": i < 3} for i, n in enumerate(names)],
         "verdict": ["wind"], "immaterial": ["temperature"]}
    ax = plot_ranking(s)
    fig = ax.figure
    fig.canvas.draw()                       # lays the figure out (constrained layout)
    box = fig.bbox
    for artist in (ax.title, ax.get_legend()):
        ext = artist.get_window_extent()
        assert box.x0 <= ext.x0 and ext.x1 <= box.x1 and box.y0 <= ext.y0 and ext.y1 <= box.y1, (artist, ext, box)
    assert [t.get_text() for t in ax.get_legend().get_texts()] == [
        "verdict", "detectable but immaterial", "significant alone", "the rest"]
