"""Atomic output files: readable permissions, and nothing left behind on failure."""

from __future__ import annotations

import os
import stat

import numpy as np
import pytest

from doorloc.fileio import atomic_write_image, atomic_write_text


def test_text_replaces_whole_file_with_plain_permissions(tmp_path):
    p = tmp_path / "sub" / "a.yaml"
    atomic_write_text(p, "old\n")
    atomic_write_text(p, "new\n")
    assert p.read_text() == "new\n"
    mask = os.umask(0)
    os.umask(mask)
    assert stat.S_IMODE(p.stat().st_mode) == 0o666 & ~mask
    assert [f.name for f in p.parent.iterdir()] == ["a.yaml"]


def test_unencodable_image_leaves_nothing(tmp_path):
    with pytest.raises(ValueError, match="cannot encode"):
        atomic_write_image(tmp_path / "x.notaformat", np.zeros((4, 4), np.uint8))
    assert list(tmp_path.iterdir()) == []


def test_image_round_trips(tmp_path):
    import cv2

    img = (np.arange(64, dtype=np.uint8).reshape(8, 8)) * 3
    atomic_write_image(tmp_path / "x.png", img)
    np.testing.assert_array_equal(cv2.imread(str(tmp_path / "x.png"), cv2.IMREAD_UNCHANGED), img)
