"""The compiled block integrator keeps no reference counting in its loops.

numba increfs the arrays a helper receives and LLVM's reference-count pruning removes the pairs;
when one pair cannot be removed (an array released on two exits of a loop), the pruning gave
up for the whole kernel and every RK4 step called the runtime's atomic incref/decref ~30 times
(a third of a wind-table batch's time). Compiled afresh (a cached kernel cannot be inspected)."""
import re

import numpy as np
import pytest
from numba import njit

from bayesdrag.air.atmosphere import Atmosphere
from bayesdrag.dynamics import kernel as K
from bayesdrag.dynamics.pointmass import PointMassModel
from bayesdrag.dynamics.trajectory import initial_state, output_schedule
from bayesdrag.air.wind import WindProfile


def _kernel_function_ir(fn):
    """LLVM IR of ``fn``'s compiled body (not its Python wrapper, which unboxes with refcounts)."""
    ir = fn.inspect_llvm(fn.signatures[0])
    bodies = [f for f in re.split(r"\ndefine ", ir) if re.match(r"[^@]*@_ZN\d+bayesdrag", f)]
    assert len(bodies) == 1
    return bodies[0]


@pytest.mark.parametrize("noalias", [True, False])
def test_wind_table_kernel_has_no_reference_counting_left(noalias, m101):
    opts = dict(pipeline_class=K._NoAliasCompiler) if noalias else {}
    probe = njit(nogil=True, no_cfunc_wrapper=True, **opts, **K._OPTS)(
        K._renamed(K.integrate_blocks.py_func, f"integrate_blocks_probe_{noalias}"))
    model = PointMassModel(42.6, 0.155, m101).with_(atmosphere=Atmosphere(wind=WindProfile.layered(
        "altitude", (0.0, 500.0, 1500.0), (-3.0, -6.0), (1.0, 2.0))))
    B, nl = 8, 8 if noalias else 1
    t = np.linspace(0.0, 5.0, 51)
    s0 = np.stack([initial_state(800.0 + 2.0 * i, 15.0) for i in range(B)])
    h, n_steps, out_step, out_theta = output_schedule(t, 0.0, model.kernel_step)
    par, cd_tabs, cd_idx, grid, atm_tabs, atm_idx, z0, dz, (w_tabs, w_idx, w0, dw) = model.kernel_inputs(
        np.zeros((B, 0)), None, None, s0, None)
    n_blk = B // nl
    out, mach = np.full((B, t.size, 6), np.nan), np.full((B, t.size), np.nan)
    probe(0, n_blk, s0, 0.0, h, n_steps, out_step, out_theta, par, cd_tabs.reshape(-1), cd_tabs.shape[1], cd_idx,
          grid.m0, grid.dm, atm_tabs.reshape(-1), atm_tabs.shape[1], atm_idx, z0, dz, w_tabs.reshape(-1),
          w_tabs.shape[1], w_idx, w0, dw, nl, False, out, mach, *K._scratch(n_blk, nl))
    assert np.all(np.isfinite(out))
    body = _kernel_function_ir(probe)
    calls = re.findall(r"call \w+ @(NRT_incref|NRT_decref)\(", body)
    assert calls == [], f"{len(calls)} reference-count calls left in the compiled kernel"
