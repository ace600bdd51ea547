"""The on-disk cache of modal data (issue 23: "the modes are computed once and cached with the
compiled code"): a second process reads the modes instead of solving the eigenproblem, a file
of another key, a truncated or a non-finite file is a miss, and what is read back equals what
was computed (bit for bit: npz stores float64 exactly)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import private_cache

from casmbd.compiled import modal_cache
from casmbd.model import flexible_bodies, modal_reduction
from casmbd.model.fe_beam import beam_model

_cache = private_cache(autouse=False)


@pytest.fixture
def beam():
    return beam_model(2.0, 6, EA=1e6, EI=50.0, rhoA=1.5, nodes={"root": 0.0, "tip": 2.0})


def test_second_lookup_reads_the_disk(_cache, beam, monkeypatch):
    flexible_bodies._MODES.clear()
    first = flexible_bodies.modal_data(beam, "craig_bampton", 3, ["root", "tip"],
                                      store=modal_cache.DISK_STORE)
    files = list(_cache.glob("modes_*.npz"))
    assert len(files) == 1
    flexible_bodies._MODES.clear()  # a new process: only the disk remains

    def refuse(*args, **kwargs):
        raise AssertionError("the eigenproblem was solved again")

    monkeypatch.setattr(flexible_bodies, "reduce", refuse)
    second = flexible_bodies.modal_data(beam, "craig_bampton", 3, ["root", "tip"],
                                      store=modal_cache.DISK_STORE)
    for name in ("positions", "masses", "inertias", "phi_t", "phi_r", "mass", "stiffness",
                 "frequencies", "rigid_mass", "rigid_coupling"):
        assert np.array_equal(getattr(first, name), getattr(second, name)), name
    assert second.node_names == first.node_names and second.reference == first.reference
    assert second.reduction == "craig_bampton" and second.key == first.key


def test_bad_files_are_misses(_cache, beam):
    flexible_bodies._MODES.clear()
    modal = modal_reduction.free_modes(beam, 2)
    modal_cache.save_modes("a" * 64, modal)
    path = next(_cache.glob("modes_*.npz"))
    assert modal_cache.load_modes("a" * 64) is not None
    assert modal_cache.load_modes("a" * 32 + "b" * 32) is None  # same file name, other key
    data = dict(np.load(path, allow_pickle=False))
    data["phi_t"] = np.full_like(data["phi_t"], np.nan)
    np.savez(path, **data)
    assert modal_cache.load_modes("a" * 64) is None  # non-finite
    path.write_bytes(path.read_bytes()[:100])
    assert modal_cache.load_modes("a" * 64) is None  # truncated
