"""Type stubs of the native extension ``brainshift._native``."""

import os
import pathlib
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

_Path = Union[str, os.PathLike[str]]
_Skull = Union[_Path, Tuple[npt.ArrayLike, npt.ArrayLike]]

__version__: str

class BrainshiftError(Exception):
    """A scene, mesh, sweep or run that brainshift refuses, with the command line's
    message; ``kind`` names the error kind ("Set", "Skull", "Solve", ...)."""

    kind: str

class Scene:
    def __init__(
        self,
        nodes: npt.ArrayLike,
        elements: npt.ArrayLike,
        *,
        regions: Sequence[Mapping[str, Any]],
        boundaries: Sequence[Mapping[str, Any]],
        node_sets: Optional[Mapping[str, Sequence[int]]] = None,
        element_sets: Optional[Mapping[str, Sequence[int]]] = None,
        skull: Optional[_Skull] = None,
        contact_algorithm: str = "paper",
        units: str = "mm",
        element: Optional[str] = None,
        solver: Optional[Mapping[str, Any]] = None,
    ) -> None: ...
    @staticmethod
    def from_toml(path: _Path) -> Scene: ...
    @property
    def path(self) -> pathlib.Path: ...
    @property
    def warnings(self) -> List[str]: ...
    @property
    def num_nodes(self) -> int: ...
    @property
    def num_elements(self) -> int: ...
    def check(self) -> Dict[str, Any]: ...
    def run(
        self,
        threads: Optional[int] = None,
        progress: Optional[Callable[[Dict[str, Any]], None]] = None,
    ) -> Result: ...

class Result:
    @property
    def displacements(self) -> npt.NDArray[np.float64]: ...
    @property
    def node_ids(self) -> npt.NDArray[np.uint64]: ...
    @property
    def report(self) -> Dict[str, Any]: ...
    def write(self, dir: _Path) -> Dict[str, pathlib.Path]: ...
    def warp(
        self, image: _Path, labels: bool = False
    ) -> Tuple[npt.NDArray[Any], npt.NDArray[np.float64]]: ...
    def field(self, reference: _Path) -> Tuple[npt.NDArray[np.float32], npt.NDArray[np.float64]]: ...

class Session:
    def __init__(self, scene: Scene, threads: Optional[int] = None) -> None: ...
    def update(
        self,
        displacements: Optional[Mapping[str, npt.ArrayLike]] = None,
        surface: Optional[Mapping[str, Union[_Path, Tuple[npt.ArrayLike, npt.ArrayLike]]]] = None,
        landmarks: Optional[Mapping[str, Union[_Path, Tuple[npt.ArrayLike, npt.ArrayLike]]]] = None,
        progress: Optional[Callable[[Dict[str, Any]], None]] = None,
    ) -> Result: ...
    def reset(self) -> None: ...
    def set_nodes(self, name: str) -> List[int]: ...

def read_mesh(path: _Path) -> Dict[str, Any]: ...
def gap(skull: _Skull, points: npt.ArrayLike, algorithm: str = "paper") -> Dict[str, Any]: ...
def sweep_plan(sweep_file: _Path, out: _Path) -> Dict[str, Any]: ...
def sweep_run(dir: _Path, index: int, threads: Optional[int] = None) -> str: ...
def sweep_collect(
    dir: _Path, points: Optional[Union[_Path, Mapping[str, Sequence[float]]]] = None
) -> List[Dict[str, Any]]: ...
def sweep_emit_slurm(
    dir: _Path,
    max_parallel: Optional[int] = None,
    time: str = "01:00:00",
    cpus_per_task: int = 2,
    program: str = "brainshift",
) -> pathlib.Path: ...
