"""The kernels compiled ahead of a device lease (``benchmarks/bench_gpu_kernels.py``) are the ones a GPU
loads: the modules one step of a model launches, traced here on Warp's CPU device, do not depend on the
number of worlds the trace was made with (the script traces one world of each structure; the GPU steps
up to hundreds), nor on the device MuJoCo Warp branches on (it asks ``wp.get_device()`` in a few places,
here made to answer as an H100/H200 would).  If a mujoco-warp release changes either, the ahead-of-time
cache would miss on the GPU and these tests say so before a lease is spent on it."""

from __future__ import annotations

import math
import sys

import pytest

from undulate import Scene

warp = pytest.importorskip("warp", reason="the gpu extra (mujoco-warp, warp-lang) is not installed")
pytest.importorskip("mujoco_warp")


@pytest.fixture(scope="module")
def kernels(benchmark_script):
    return benchmark_script("bench_gpu_kernels")


class _AsCuda:
    """A Warp device that answers MuJoCo Warp's questions as a 132-SM CUDA device would."""

    is_cuda, is_cpu, sm_count = True, False, 132

    def __init__(self, device):
        self._device = device

    def __getattr__(self, name):
        return getattr(self._device, name)


def _identifiers(kernels, scenes, as_cuda: bool = False) -> set:
    """The (module identifier, CUDA block size) pairs the script compiles for ``scenes``' model."""
    import warp as wp

    real = wp.get_device
    asked = []

    def device(*args, **kw):  # only MuJoCo Warp's own questions are answered as on a GPU
        d = real(*args, **kw)
        if sys._getframe(1).f_globals.get("__name__", "").startswith("mujoco_warp"):
            asked.append(1)
            return _AsCuda(d)
        return d

    if as_cuda:
        wp.get_device = device
    try:
        ids = {(m.get_module_identifier(block_dim=bd), bd) for m, bd in kernels._traced(list(scenes), False)}
    finally:
        wp.get_device = real
    assert not as_cuda or asked, "MuJoCo Warp asked nothing of the device: the CUDA branches were not reached"
    return ids


def _pack(draw: int) -> Scene:
    from undulate.studies.packing import _pack as pack

    return pack({"phi_max_rad": math.pi, "rho_tilde": 3.0, "draw": draw}, amplitude_m=0.05226, base_seed=0,
                n_swimmers=50)[0]


def test_a_pairs_kernels_are_the_same_for_one_world_or_many_and_on_a_gpu(kernels):
    pairs = [Scene(phases_rad=(0.0, 0.3 * k)) for k in range(1, 37)]
    one = _identifiers(kernels, pairs[:1])
    assert len(one) >= 30  # MuJoCo Warp's pipeline and our control and recording kernels
    assert _identifiers(kernels, pairs) == one
    assert _identifiers(kernels, pairs[:1], as_cuda=True) == one


def test_a_jammed_packs_kernels_are_the_same_for_one_world_or_two_and_on_a_gpu(kernels):
    one = _identifiers(kernels, [_pack(0)])
    assert _identifiers(kernels, [_pack(0), _pack(1)]) == one
    assert _identifiers(kernels, [_pack(0)], as_cuda=True) == one
