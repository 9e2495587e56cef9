"""A toy effect, whole in this one module: the radar's speed reads a constant factor ``1 + s``
too high (a range-rate scale error, on a gun-frame track its ``v`` channel). It is what a
maintainer writes to add an effect (docs/architecture.md, "Adding an effect"): an
:class:`~bayesdrag.effects.Effect` with its parameters, its traits and its one mapping to the
simulation's inputs. No package file names it; :func:`bayesdrag.effects.registered` adds it to
the library for a ``with`` block (tests/unit/test_toy_effect.py)."""
from bayesdrag.effects import Effect, ExtraParam

#: bound of the fitted scale error [-] (a radar 5 % off in speed is not calibrated)
SPEED_SCALE_MAX = 0.05


def speed_scale_inputs(values, ctx, state0):
    """The radar's speed times ``1 + s`` (``SimInputs.output_scale``); values (B, 1)."""
    return {"output_scale": {"v": 1.0 + values[:, 0]}}


#: the effect; ``source``: the stem a declared source of the same quantity would have
SPEED_SCALE = Effect(
    "speed_scale", (ExtraParam("s", 0.0, -SPEED_SCALE_MAX, SPEED_SCALE_MAX, 1e-5),), ("-",),
    "The radar's speed reads a constant factor 1 + s off (its range-rate calibration): every speed it "
    "records is the true one times 1 + s.",
    acts_on="measurement", source="speed_scale", to_inputs=speed_scale_inputs)
