"""decrun.core.digest: its canonical forms, checked against sha256 written out by hand."""

from __future__ import annotations

import hashlib
import json

import numpy as np

from decrun.core.digest import BLOCK_BYTES, Digest, file_record, text_sha256


def test_text_and_json_are_their_utf8_bytes():
    assert text_sha256("Δ = dδ + δd") == hashlib.sha256("Δ = dδ + δd".encode()).hexdigest()
    value = {"b": [1, 2.5], "a": {"z": None, "y": "é"}}
    expected = hashlib.sha256(json.dumps(value, sort_keys=True).encode()).hexdigest()
    assert Digest().json(value).hexdigest() == expected
    # key order does not matter; values do
    assert Digest().json({"a": {"y": "é", "z": None}, "b": [1, 2.5]}).hexdigest() == expected
    assert Digest().json({"a": {"y": "é", "z": None}, "b": [1, 2.0]}).hexdigest() != expected


def test_array_form_is_dtype_shape_then_c_order_bytes():
    fortran = np.asfortranarray(np.arange(6, dtype=np.float64).reshape(2, 3))
    expected = hashlib.sha256(b"<f8 (2, 3) " + np.ascontiguousarray(fortran).tobytes()).hexdigest()
    assert Digest().array(fortran).hexdigest() == expected
    # the same numbers in another dtype or shape are another identity
    assert Digest().array(fortran.astype(np.float32)).hexdigest() != expected
    assert Digest().array(fortran.reshape(3, 2)).hexdigest() != expected
    # without the header: the bytes alone; a 0-d array is its one value's bytes
    assert Digest().array(fortran, header=False).hexdigest() == hashlib.sha256(fortran.tobytes("C")).hexdigest()
    assert Digest().array(np.float64(0.5), header=False).hexdigest() == hashlib.sha256(
        np.float64(0.5).tobytes()).hexdigest()
    assert Digest().array(np.zeros((0, 3)), header=False).hexdigest() == hashlib.sha256(b"").hexdigest()
    assert Digest().array([1, 2], "<i8").hexdigest() == hashlib.sha256(
        b"<i8 (2,) " + np.array([1, 2], "<i8").tobytes()).hexdigest()


def test_salt_and_prefix_digits():
    assert Digest(b"salt").text("x").hexdigest() == hashlib.sha256(b"saltx").hexdigest()
    assert Digest().text("x").hexdigest(16) == hashlib.sha256(b"x").hexdigest()[:16]


def test_file_record_streams_the_file(tmp_path):
    data = np.random.default_rng(0).bytes(2 * BLOCK_BYTES + 123)  # three blocks, the last one short
    path = tmp_path / "blob"
    path.write_bytes(data)
    assert file_record(path) == {"bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}
    empty = tmp_path / "empty"
    empty.write_bytes(b"")
    assert file_record(empty) == {"bytes": 0, "sha256": hashlib.sha256(b"").hexdigest()}
