"""The shipped test sets (``sidar_torch.evaluation.testsets``): published definitions never change, they are
whole (a digest for every file of every sequence), and rebuilding a set's first sequences on the
renderer that recorded it reproduces their digests."""

import dataclasses

import pytest

from sidar_torch import load_config
from sidar_torch.evaluation.testsets import (available_testsets, check_digests, definition_digest,
                                                     export_testset, file_digests, load_testset, rasteriser_name,
                                                     same_rasteriser)

from recorded import rasteriser_mismatch

PUBLISHED = {
    "homography-v1": "a12b5b04ec85f6a72477ce38f7bd77a995f7ad0576c12a0a8684ac944ee3f052",
    "shadow-removal-v1": "3741fe9824701313e46d3e3809b7cb655d1ecd10a5351dddc1bdd5139700ff7d",
}
"""SHA-256 of each published definition file. Never edit an entry: a changed set is a new name
(``-v2``) with an entry of its own (``scripts/record_testset.py`` writes its definition)."""


def test_every_shipped_set_is_published_and_unchanged():
    assert available_testsets() == sorted(PUBLISHED)
    for name, digest in PUBLISHED.items():
        assert definition_digest(name) == digest, f"{name} changed: publish the change as a new name (-v2)"


@pytest.mark.parametrize("name", sorted(PUBLISHED))
def test_a_definition_is_whole_and_its_configs_load(name):
    testset = load_testset(name)
    assert testset.name == name and testset.task in ("homography", "shadow-removal") and testset.pairs == "reference"
    for category in testset.categories:
        config = load_config(None, **category.config)
        names = [key.split("/") for key in testset.digests if key.startswith(f"{category.name}/")]
        assert {folder for _, folder, _ in names} == {f"{i:06d}" for i in range(category.count)}
        first = {file for _, folder, file in names if folder == "000000"}
        expected = {"0.png", "0-m.png", "gt.png", "cameras.json", "H_0_1.mat", "H_1_0.mat"}
        expected |= {"0-s.png"} if config.shadow_mask_output else set()
        expected |= {"0-f.png"} if config.shadow_free_output else set()
        assert expected <= first and len(names) == len(first) * category.count  # every sequence: the same files
    assert testset.recorded_on["gl_renderer"] and testset.recorded_on["gl_version"]


def test_a_digest_check_names_the_files_that_differ_and_why_they_may(tmp_path):
    testset = load_testset("homography-v1")
    name = "clean/000000/1.png"
    (tmp_path / "clean" / "000000").mkdir(parents=True)
    (tmp_path / "clean" / "000000" / "1.png").write_bytes(b"not the recorded bytes")
    check = check_digests(testset, tmp_path, renderer={"gl_renderer": "another renderer", "gl_version": "4.5 Mesa 99"})
    assert file_digests(tmp_path) == {name: file_digests(tmp_path)[name]}
    assert check.checked == 1 and check.differing == (name,) and not check.matches
    assert "1 of 1 files differ" in check.summary() and "another renderer, 4.5 Mesa 99" in check.summary()
    assert "Mesa 22.3.6" in check.summary()  # the v1 files name llvmpipe's LLVM only; Mesa's release drew other pixels
    assert "evaluate" in check.summary()


def test_pixels_compare_only_on_the_renderer_and_mesa_release_they_were_recorded_on():
    here = {"gl_renderer": "llvmpipe (LLVM 15.0.6, 256 bits)", "gl_version": "4.5 (Core Profile) Mesa 25.0.7"}
    assert same_rasteriser(dict(here, python="3.11.7"), here)
    # Mesa 25.0.7 on the same LLVM draws other pixels than 22.3.6: the renderer string alone cannot tell
    assert not same_rasteriser(dict(here, gl_version="4.5 (Core Profile) Mesa 22.3.6"), here)
    assert not same_rasteriser(dict(here, gl_renderer="llvmpipe (LLVM 19.1.7, 256 bits)"), here)
    assert same_rasteriser({"gl_renderer": here["gl_renderer"]}, here)  # a record naming no version: the renderer
    assert rasteriser_name({"gl_renderer": "x"}) == "x, GL version not recorded"


@pytest.mark.gl
def test_rebuilding_the_first_sequences_of_a_set_reproduces_their_digests(tmp_path):
    testset = load_testset("homography-v1")
    first = dataclasses.replace(testset, categories=(testset.categories[0], testset.categories[-1]))  # clean, all
    check = export_testset(first, tmp_path, sequences=1, progress=False)
    mismatch = rasteriser_mismatch(testset.recorded_on)
    if mismatch is not None:
        pytest.skip(f"pixels not compared: {mismatch}")
    # Every image file is the recorded bytes. The float64 files (cameras.json, H_i_j.mat) hold the same
    # geometry within 1e-9 on any machine (tests/test_stored_digests.py) but not always its last bits:
    # numpy's and torch's float64 kernels follow the CPU's vector width (on an AVX-512 EPYC, 2026-11-28,
    # 24 of these 52 files differed, the landed commit 239d642 included, while every PNG matched).
    pixels = [name for name in check.differing if not name.endswith((".json", ".mat"))]
    assert check.checked == 2 * 26 and not pixels, check.summary()
