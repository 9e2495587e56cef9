"""Where each block of a fit's parameter vector sits: the drag coefficients, the initial state,
the effects' parameters (``theta = [drag (P), state (6), effects (E)]``).

One home for the layout that the problem, the ML result, the Scheme 1 recipe, the launch priors
and the planner index into, instead of literal offsets."""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["STATE", "N_STATE", "ParameterLayout"]

#: the initial state's components in order: position [m] and ground velocity [m/s], gun frame
STATE = ("x", "y", "z", "vx", "vy", "vz")
#: their number
N_STATE = len(STATE)


@dataclass(frozen=True)
class ParameterLayout:
    """The blocks of a parameter vector of ``n_drag`` drag coefficients, the initial state and
    ``n_effects`` effect parameters.

    Examples
    --------
    >>> lay = ParameterLayout(4, 2)
    >>> lay.state, lay.index("vy"), lay.size
    (slice(4, 10, None), 8, 12)
    """

    n_drag: int
    n_effects: int = 0

    @property
    def drag(self) -> slice:
        """The drag coefficients."""
        return slice(0, self.n_drag)

    @property
    def state(self) -> slice:
        """The initial state ``x, y, z, vx, vy, vz``."""
        return slice(self.n_drag, self.n_drag + N_STATE)

    @property
    def position(self) -> slice:
        """The initial position ``x, y, z`` [m]."""
        return slice(self.n_drag, self.n_drag + 3)

    @property
    def velocity(self) -> slice:
        """The initial velocity ``vx, vy, vz`` [m/s]."""
        return slice(self.n_drag + 3, self.n_drag + N_STATE)

    @property
    def effects(self) -> slice:
        """The effects' parameters (after the state)."""
        return slice(self.n_drag + N_STATE, self.size)

    @property
    def size(self) -> int:
        """Length of the whole vector."""
        return self.n_drag + N_STATE + self.n_effects

    def index(self, component: str) -> int:
        """Position of one state component (``"x"`` ... ``"vz"``) in the vector."""
        return self.n_drag + STATE.index(component)
