"""The radar's own systematic sources (issue 28): range, azimuth and elevation biases and the
radar's site as nuisance parameters. Each moves exactly the channels it should, by exactly what
the measurement equations say, and the ones the fit cannot carry are stated."""
import math

import numpy as np
import pytest

from bayesdrag.effects.inputs import SimInputs
from bayesdrag.estimate.model.problem import outputs
from bayesdrag.estimate.build import sources as S
from bayesdrag.measure import RadarSite, channel_values
from bayesdrag.round import Launch, Projectile, Radar, Round

#: agreement of two evaluations of the same measurement equations [channel units]
EXACT = 1e-9
NATIVE = ("range", "azimuth", "elevation", "range_rate")


def _states(rng, b=3, n=5):
    pos = np.stack([rng.uniform(500, 9000, (b, n)), rng.uniform(-300, 300, (b, n)), rng.uniform(10, 4000, (b, n))], -1)
    vel = np.stack([rng.uniform(200, 800, (b, n)), rng.uniform(-20, 20, (b, n)), rng.uniform(-300, 300, (b, n))], -1)
    return np.concatenate([pos, vel], axis=-1)


def test_offsets_and_site_shift_are_the_biased_moved_radar(rng):
    """Per trajectory: outputs with the bias offsets and a shifted site equal the channels of a
    RadarSite that stands at the shifted position with those biases; gun channels untouched."""
    st = _states(rng)
    site = RadarSite((-40.0, 25.0, 2.0), math.radians(90.0))
    shift = rng.normal(0.0, 0.5, (3, 3))
    rb, ab, eb = rng.normal(0, 1, 3), rng.normal(0, 1e-3, 3), rng.normal(0, 1e-3, 3)
    chans = ("x", "v") + NATIVE
    got = outputs(st, chans, site, offset={"range": rb, "azimuth": ab, "elevation": eb}, site_shift=shift)
    for b in range(3):
        moved = RadarSite(tuple(np.add(site.position, shift[b])), site.azimuth, rb[b], ab[b], eb[b])
        want = channel_values(st[b], chans, moved)
        diff = got[b] - want
        j = chans.index("azimuth")
        diff[:, j] = (diff[:, j] + np.pi) % (2 * np.pi) - np.pi
        assert np.max(np.abs(diff)) < EXACT


def _round(**radar):
    return Round(Projectile(mass=42.6, diameter=0.155), Launch(45.0, 818.0, azimuth_deg=90.0),
                 radar=Radar({}, position=(-40.0, 25.0, 2.0), **radar))


def test_radar_extras_follow_the_channels():
    rnd = _round(range_bias_sd=1.0, elevation_bias_sd=math.radians(0.05), position_sd=0.2)
    names = [e[1].name for e in S.source_extras(rnd, ("range", "elevation", "range_rate"))]
    assert names == ["range_bias", "elevation_bias", "radar_position.x", "radar_position.y", "radar_position.z"]
    # a Doppler-only track: no range or elevation channel, the site still matters
    assert [e[0] for e in S.source_extras(rnd, ("range_rate",))] == ["radar_position"] * 3
    # gun-frame channels depend on none of them, and the fit says the declared ones are not fitted
    assert S.source_extras(rnd, ("x", "y", "z", "v")) == ()
    unused = S.radar_unused(rnd, ("x", "y", "z", "v"))
    assert set(unused) == {"range_bias", "elevation_bias", "radar_position"}
    assert "not fitted" in unused["range_bias"]


def test_undeclared_sources_the_channels_depend_on_are_named():
    assert S.radar_conditional(("range_rate",), set()) == ["radar_position"]
    assert S.radar_conditional(NATIVE, {"radar_position"}) == ["range_bias", "azimuth_bias", "elevation_bias"]
    assert S.radar_conditional(("x", "y", "z", "v"), set()) == []


def test_source_fn_turns_the_parameters_into_offsets_and_a_site_shift():
    rnd = _round(azimuth_bias_sd=math.radians(0.05), position_sd=0.2)
    ex = S.source_extras(rnd, NATIVE)
    fn = S.source_fn(ex, rnd, model=None)
    E = np.array([[1e-4, 0.1, -0.2, 0.3], [0.0, 0.0, 0.0, 0.0]])
    inp = fn(E)
    assert isinstance(inp, SimInputs)
    assert inp.output_offset["azimuth"] == pytest.approx([1e-4, 0.0])
    assert inp.site_shift == pytest.approx(np.array([[0.1, -0.2, 0.3], [0.0, 0.0, 0.0]]))
    pri = S.source_priors(ex, 10)
    assert [p.name for p in pri] == ["azimuth_bias_sd", "radar_position_sd.x", "radar_position_sd.y",
                                     "radar_position_sd.z"]
    assert [p.sd for p in pri] == pytest.approx([math.radians(0.05), 0.2, 0.2, 0.2])


def test_chronograph_correction_and_its_jacobian():
    """A chronograph radar reports range_rate * R / sqrt(R^2 - d^2) for the offset d typed into
    it: exactly the speed for a shell flying straight past a site at that offset, and the
    analytic Jacobian of the corrected channel matches finite differences."""
    d = 0.4
    site = RadarSite((0.0, d, 0.0), 0.0, device_offset=d)
    x = np.linspace(2.0, 80.0, 30)
    st = np.column_stack([x, np.zeros_like(x), np.zeros_like(x), np.full_like(x, 850.0),
                          np.zeros_like(x), np.zeros_like(x)])
    rr = channel_values(st, ("range_rate",), site)[:, 0]
    assert np.max(np.abs(rr - 850.0)) < EXACT * 850.0                # the device's own correction, exact
    raw = channel_values(st, ("range_rate",), RadarSite((0.0, d, 0.0), 0.0))[:, 0]
    assert np.all(raw < rr)                                          # uncorrected: a cosine short
    from bayesdrag.measure import channel_jacobian
    rng = np.random.default_rng(3)
    st = np.column_stack([rng.uniform(3, 60, 20), rng.uniform(-1, 1, 20), rng.uniform(-1, 2, 20),
                          rng.uniform(600, 900, 20), rng.uniform(-5, 5, 20), rng.uniform(-5, 20, 20)])
    J = channel_jacobian(st, ("range_rate",), site)[:, 0, :]
    h = 1e-5
    for k in range(6):
        sp, sm = st.copy(), st.copy()
        sp[:, k] += h
        sm[:, k] -= h
        fd = (channel_values(sp, ("range_rate",), site) - channel_values(sm, ("range_rate",), site))[:, 0] / (2 * h)
        assert np.allclose(fd, J[:, k], rtol=1e-5, atol=1e-6), k


def test_round_file_device_offset_gives_the_site_and_bad_offsets_are_refused(tmp_path):
    from bayesdrag.errors import InputError
    from bayesdrag.io.rounds import read_round, write_round

    head = "[projectile]\nmass = 0.042\ndiameter = 0.0127\n[launch]\nelevation = 1.0\nvelocity = 880.0\n"
    p = tmp_path / "c.toml"
    p.write_text(head + "[radar]\ndevice_offset = 0.3\nposition_sd = 0.2\n")
    rnd = read_round(p)
    assert rnd.radar.position == (0.0, 0.3, 0.0) and rnd.radar.device_offset == 0.3
    from bayesdrag.measure import site_of
    assert site_of(rnd).device_offset == 0.3
    # a site given explicitly (here the muzzle) survives a round trip, not replaced by the offset's
    muzzle = Round(rnd.projectile, rnd.launch, radar=Radar({}, position=(0.0, 0.0, 0.0), device_offset=0.3))
    write_round(tmp_path / "m.toml", muzzle)
    assert read_round(tmp_path / "m.toml").radar.position == (0.0, 0.0, 0.0)
    p.write_text(head + "[radar]\ndevice_offset = -0.3\n")
    with pytest.raises(InputError, match=r"c\.toml.*device_offset = -0\.3 m is not a chronograph radar's offset"):
        read_round(p)
