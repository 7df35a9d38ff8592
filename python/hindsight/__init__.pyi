# Type stubs of the public API of hindsight (python/hindsight/__init__.py, where the docstrings are).
import os
from typing import Any, Callable, Dict, List, Optional, Protocol, Union

import numpy as np
import numpy.typing as npt

from ._hindsight import NumericalError as NumericalError
from ._hindsight import StorageError as StorageError
from ._hindsight import storage_strategy_names as storage_strategy_names
from .checkpoint_schedule import Copy as Copy
from .checkpoint_schedule import EndForward as EndForward
from .checkpoint_schedule import EndReverse as EndReverse
from .checkpoint_schedule import Forward as Forward
from .checkpoint_schedule import Move as Move
from .checkpoint_schedule import Reverse as Reverse
from .checkpoint_schedule import StorageType as StorageType
from .checkpoint_schedule import checkpoint_schedule as checkpoint_schedule

__version__: str
__all__: List[str]

ConfigLike = Union[None, str, os.PathLike, Dict[str, Any]]
Array = npt.NDArray[np.float64]

class Result(Dict[str, Any]):
    """A dict whose keys are also attributes: r.psi1 is r["psi1"]."""
    def __getattr__(self, name: str) -> Any: ...

class ForwardProblem(Protocol):
    """What hindsight.simulate needs of a problem written in Python (integrand is optional)."""
    state_size: int
    parameter_size: int
    def initial_state(self, p: Array) -> npt.ArrayLike: ...
    def rhs(self, t: float, z: Array, p: Array) -> npt.ArrayLike: ...

class Problem(ForwardProblem, Protocol):
    """What hindsight.gradient needs of a problem written in Python. Its derivative methods
    (rhs_jacobian, rhs_state_vjp, rhs_parameter_vjp, integrand_state_gradient,
    integrand_parameter_gradient, initial_state_vjp, terminal_gradient) are optional: the missing ones
    are generated (derivatives="auto")."""
    def integrand(self, t: float, z: Array, p: Array) -> float: ...

def config(config: ConfigLike = None, **overrides: Any) -> Dict[str, Any]: ...

class PistonRod:
    def __init__(self, config: ConfigLike = None, **overrides: Any) -> None: ...
    @property
    def config(self) -> Dict[str, Any]: ...
    @property
    def x0(self) -> Array: ...
    @property
    def shape(self) -> tuple[int, int]: ...
    @property
    def design_count(self) -> int: ...
    def design_variables(self, x: npt.ArrayLike) -> Array: ...
    def design_grid(self, values: npt.ArrayLike, interface_value: float = 1.0) -> Array: ...
    def evaluate(self, x: Optional[npt.ArrayLike] = None, gradient: bool = True, storage: Optional[str] = None,
                 adjoint: Optional[str] = None, integrator: Optional[str] = None, psi2: bool = True) -> Result: ...


class Mechanism(PistonRod):
    def __init__(self, description: Union[Dict[str, Any], str, "os.PathLike[str]"], config: Optional[Dict[str, Any]] = None,
                 **overrides: Any) -> None: ...

def optimize(config: ConfigLike = None, out: Union[str, os.PathLike] = "results", resume: bool = False,
             force: bool = False, callback: Optional[Callable[[Dict[str, Any]], Optional[bool]]] = None,
             verbose: bool = False, **overrides: Any) -> Result: ...
def read_results(path: Union[str, os.PathLike]) -> Result: ...
def history_columns() -> List[Result]: ...
def plot_comparison(*runs: Union[str, os.PathLike, Dict[str, Any]], out: Optional[Union[str, os.PathLike]] = None) -> Any: ...
Tolerance = Union[float, npt.ArrayLike]

def gradient(problem: Problem, p: npt.ArrayLike, integrator: str = "rk4", step: float = 1e-3, t0: float = 0.0,
             t1: float = 1.0, storage: str = "full", adjoint: str = "discrete", adaptive: bool = False,
             rtol: float = 1e-6, atol: Tolerance = 1e-9, derivatives: str = "auto", *,
             min_step: Optional[float] = None, max_step: Optional[float] = None, max_steps: Optional[int] = None,
             newton_tolerance: Optional[float] = None, newton_max_iterations: Optional[int] = None,
             rho_infinity: Optional[float] = None) -> Result: ...
def classic_gradient(name: str, p: npt.ArrayLike, integrator: str = "rk4", step: float = 1e-3, t0: float = 0.0,
                     t1: float = 1.0, storage: str = "full", adjoint: str = "discrete", adaptive: bool = False,
                     rtol: float = 1e-6, atol: Tolerance = 1e-9, *, min_step: Optional[float] = None,
                     max_step: Optional[float] = None, max_steps: Optional[int] = None,
                     newton_tolerance: Optional[float] = None, newton_max_iterations: Optional[int] = None,
                     rho_infinity: Optional[float] = None) -> Result: ...
def simulate(problem: Union[str, ForwardProblem], p: npt.ArrayLike, times: Optional[npt.ArrayLike] = None,
             observer: Optional[Callable[[float, Array], Optional[bool]]] = None, integrator: str = "rk4",
             step: float = 1e-3, t0: float = 0.0, t1: float = 1.0, adaptive: bool = False, rtol: float = 1e-6,
             atol: Tolerance = 1e-9, *, min_step: Optional[float] = None, max_step: Optional[float] = None,
             max_steps: Optional[int] = None, newton_tolerance: Optional[float] = None,
             newton_max_iterations: Optional[int] = None, rho_infinity: Optional[float] = None) -> Result: ...
def storage_specs() -> List[Result]: ...
def schedule(spec: str, steps: int, state_bytes: int, stages: int = 4, costs: Optional[str] = None,
             actions: bool = False) -> Result: ...
def check_storage_spec(spec: str) -> str: ...
