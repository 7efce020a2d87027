"""Surface reconstruction from points, curves and patches; distance fields.

numpy in (float32 or float64, any memory order), numpy out (float64
vertices, int64 faces). Every call releases the GIL while it computes.
"""

from os import PathLike
from typing import Any, Callable, Dict, List, Optional, Protocol, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

_Floats = npt.NDArray[Union[np.float32, np.float64]]
_Ints = npt.NDArray[np.integer]
_Mesh = Tuple[_Floats, _Ints]
_Path = Union[str, "PathLike[str]"]

class _Event(Protocol):
    def is_set(self) -> bool: ...

class Cancelled(Exception):
    """A run stopped by its `cancel` event or `progress` callback."""

def reconstruct(
    points: Optional[_Floats] = None,
    normals: Optional[_Floats] = None,
    curves: Optional[Sequence[_Floats]] = None,
    triangles: Optional[_Mesh] = None,
    *,
    method: str = "levelset",
    resolution: Optional[int] = None,
    report: bool = False,
    cancel: Optional[_Event] = None,
    progress: Optional[Callable[[str, int, int], Optional[bool]]] = None,
    epsilon: Optional[float] = None,
    p: Optional[float] = None,
    steps: Optional[int] = None,
    band: Optional[float] = None,
    levels: Optional[int] = None,
    bounding_box: bool = False,
    free_topology: bool = False,
    no_cleaning: bool = False,
    no_refine: bool = False,
    no_slices: bool = False,
    no_curve_network: bool = False,
    keep_pieces: bool = False,
    two_d: bool = False,
    svm_c: Union[float, str, None] = None,
    svm_epsilon: Optional[float] = None,
    svm_accuracy: Optional[float] = None,
    loss: str = "epsilon",
    drop_levels: int = 0,
    model_out: Optional[_Path] = None,
    model_in: Optional[_Path] = None,
    svm_normal_k: Optional[int] = None,
    rho: Optional[float] = None,
    rho_geom: Optional[float] = None,
    rho_topo: Optional[float] = None,
    fill_holes: Optional[int] = None,
    no_pockets: bool = False,
    no_thin_parts: bool = False,
    convection_normal_k: Optional[int] = None,
    cover_holes: bool = False,
    no_edge_flips: bool = False,
    on_the_fly: bool = False,
    no_curved_splits: bool = False,
) -> Union[Tuple[npt.NDArray[np.float64], npt.NDArray[np.int64]],
           Tuple[npt.NDArray[np.float64], npt.NDArray[np.int64], Dict[str, Any]]]:
    """Reconstruct a closed surface; (V, F), or (V, F, report) with report=True.
    See help(surfrecon.reconstruct) for every option and its default."""

def distance(
    data: Union[_Floats, _Mesh],
    *,
    resolution: Optional[int] = None,
    spacing: Optional[float] = None,
    padding: int = 4,
    signed: bool = False,
    allow_open: bool = False,
    band: Optional[float] = None,
) -> Tuple[npt.NDArray[np.float64], Tuple[float, float, float], float]:
    """(field of shape (nx, ny, nz), origin, spacing) of points or a mesh."""

def extract(
    field: _Floats, origin: Tuple[float, float, float], spacing: float, iso: float = 0.0
) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.int64]]:
    """The isosurface field = iso as (V, F) (marching cubes)."""

def evaluate(
    vertices: _Floats,
    faces: _Ints,
    reference: Union[_Floats, _Mesh],
    *,
    data: Optional[_Floats] = None,
    samples: int = 100_000,
    seed: int = 0,
) -> Dict[str, Any]:
    """Scores with the keys of `surfrecon eval --json`."""

def read(path: _Path) -> Dict[str, Any]:
    """{"vertices", "normals", "triangles", "lines"} of a geometry file."""

def write(
    path: _Path,
    vertices: _Floats,
    triangles: Optional[_Ints] = None,
    *,
    normals: Optional[_Floats] = None,
    lines: Optional[Sequence[_Ints]] = None,
) -> None:
    """Write points, a mesh or polylines (format by extension), atomically."""

def write_shell(
    path: _Path, field: _Floats, origin: Tuple[float, float, float], spacing: float
) -> None:
    """Store a signed distance field as a thin shell file (`surfrecon shell`)."""

def read_shell(path: _Path) -> Tuple[npt.NDArray[np.float64], Tuple[float, float, float], float]:
    """(field, origin, spacing) rebuilt from a thin shell file (`surfrecon unshell`)."""

def morph(
    vertices: _Floats,
    faces: _Ints,
    target: Union[_Floats, _Mesh],
    pairs: Optional[_Floats] = None,
    *,
    c_corr: Optional[float] = None,
    c_dist: Optional[float] = None,
    warp_levels: Optional[int] = None,
    report: bool = False,
    cancel: Optional[_Event] = None,
    progress: Optional[Callable[[str, int, int], Optional[bool]]] = None,
) -> Union[npt.NDArray[np.float64], Tuple[npt.NDArray[np.float64], Dict[str, Any]]]:
    """Displacements (n, 3) warping the source mesh onto the target; frame t is V + t*D."""
