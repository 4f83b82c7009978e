"""Issue 34 item 4: every config number, whatever its Python type, is a ``ValueError`` naming the
field; a config file names itself in every error; a FIFO is refused as not a regular file without
blocking."""

import os
import re
import subprocess
import sys
from decimal import Decimal
from fractions import Fraction

import numpy as np
import pytest

from sidar_torch import load_config
from sidar_torch.config.numbers import shown

HUGE = Fraction(10**400, 3)


@pytest.mark.parametrize("field, value", [
    ("max_image_pixels", HUGE), ("n_views", HUGE), ("image_size", (HUGE, 3)), ("n_lights", (0, HUGE)),  # OverflowError
    ("camera_xy", HUGE), ("camera_height", (1, -HUGE)), ("n_views", -HUGE),
    ("n_views", 10**5000), ("max_image_pixels", 10**5000), ("camera_xy", 10**5000), ("image_size", (3, -10**5000)),
    ("n_views", Decimal("3")), ("camera_xy", Decimal("NaN")), ("n_views", Decimal("sNaN")), ("n_views", Decimal("1e999999")),
    ("n_views", Fraction(5, 2)), ("n_views", np.uint64(2**64 - 1)), ("n_views", np.longdouble("1e4000")),
    ("n_views", True), ("camera_xy", np.bool_(False)), ("n_views", 3 + 0j), ("n_views", "3"), ("n_views", None),
], ids=lambda v: v if isinstance(v, str) else type(v).__name__)
def test_a_number_of_any_type_is_a_value_error_naming_the_field(field, value):
    with pytest.raises(ValueError, match=f"^override {field}=.*: config field '{field}': expected"):
        load_config("misaligned", **{field: value})


def test_an_integral_fraction_is_its_integer():
    assert load_config("misaligned", n_views=Fraction(6, 2), image_size=(Fraction(48), 64)).n_views == 3


def test_a_huge_integer_is_shown_by_its_length():
    assert shown(10**5000) == "<an integer of about 5001 digits>"
    assert shown((1, -10**5000)) == "(1, <an integer of about 5001 digits>)"


@pytest.mark.parametrize("text, named", [
    ("n_views: " + "9" * 5000, r"line 2, column 10: unreadable value \(an integer of 5000 digits"),  # ValueError, no file
    ("n_views: 1" + ":1" * 5000, "line 2, column 10: unreadable value"),  # sexagesimal: quadratic time
    ("n_views: 1000", "config field 'n_views': expected 1 <= value <= 256, got 1000"),
    ("image_size: [1, 0x" + "f" * 4000 + "]", r"config field 'image_size': expected .* got \(1, <an integer of about"),
    ("camera_xy: .nan", "config field 'camera_xy': expected a finite number"),
    ("image_size: [3000, 4000]\nn_views: 64", "config fields 'image_size', 'n_views'"),  # a rule between fields
])
def test_every_error_of_a_config_file_names_the_file(tmp_path, text, named):
    path = tmp_path / "mine.yaml"
    path.write_text("base: misaligned\n" + text + "\n")
    with pytest.raises(ValueError, match=named) as error:
        load_config(path)
    assert str(error.value).startswith(f"config file {str(path)!r}")


def test_an_override_is_named_alone_and_a_rule_between_a_file_and_overrides_names_both(tmp_path):
    path = tmp_path / "mine.yaml"
    path.write_text("base: misaligned\nimage_size: [3000, 4000]\n")
    with pytest.raises(ValueError, match="^override n_views=1000: config field 'n_views': expected 1 <= value <= 256, "
                                         "got 1000$"):
        load_config(path, n_views=1000)
    with pytest.raises(ValueError, match=rf"^overrides n_views=64 on config file {str(path)!r}: config fields 'image_size'"):
        load_config(path, n_views=64)


def test_an_overrides_own_mistake_names_the_override_not_the_preset_file(tmp_path):
    # issue 48: load_config("misaligned", n_views="x") and a rule that only the overrides break were
    # blamed on the preset's file ("config file '.../misaligned.yaml' with overrides: ...").
    with pytest.raises(ValueError, match=r"^override n_views='x': config field 'n_views': expected a number, got 'x'$"):
        load_config("misaligned", n_views="x")
    preset = "misaligned.yaml'"
    with pytest.raises(ValueError, match=rf"^overrides max_tilt_deg=89 on config file '[^']*{preset}: config field "
                                         r"'max_tilt_deg': expected at most"):
        load_config("misaligned", max_tilt_deg=89)
    with pytest.raises(ValueError, match=r"^overrides max_tilt_deg=89 on the defaults: config field 'max_tilt_deg'"):
        load_config(None, max_tilt_deg=89)
    with pytest.raises(ValueError, match=r"^overrides max_tilt_deg=89 on the SidarConfig given: config field"):
        load_config(load_config("misaligned"), max_tilt_deg=89)
    # A file that breaks a rule by itself is still named as the one to fix, with the overrides beside it.
    path = tmp_path / "steep.yaml"
    path.write_text("base: misaligned\nmax_tilt_deg: 89\n")
    with pytest.raises(ValueError, match=rf"^config file {str(path)!r} with overrides n_views=2: config field 'max_tilt_deg'"):
        load_config(path, n_views=2)


def test_a_loop_of_symbolic_links_named_as_a_config_is_a_value_error_naming_it(tmp_path):
    # issue 48: Path.resolve raised RuntimeError("Symlink loop from ...").
    first, second = tmp_path / "first.yaml", tmp_path / "second.yaml"
    first.symlink_to(second)
    second.symlink_to(first)
    with pytest.raises(ValueError, match=rf"^config file {str(first)!r}: not a regular file: expected a regular file, "
                                         r"got a loop of symbolic links"):
        load_config(first)
    (tmp_path / "child.yaml").write_text("base: first.yaml\n")
    with pytest.raises(ValueError, match=rf"^config file {str(first)!r}: not a regular file"):
        load_config(tmp_path / "child.yaml")


@pytest.mark.parametrize("size", [(1, 64), (64, 1), (1, 1)])
def test_flow_at_a_side_of_one_pixel_is_refused_naming_both_fields(size):
    # issue 48: accepted, then RuntimeError ("index -64 is out of bounds") in the first sample's flow.
    with pytest.raises(ValueError, match=rf"config fields 'flow_output' and 'image_size': expected an image_size of at "
                                         rf"least 2 x 2 pixels \(H, W\) with flow_output true .*got {re.escape(str(size))}"):
        load_config("misaligned", image_size=size, flow_output=True)
    assert load_config("misaligned", image_size=size, depth_output=True).image_size == size  # depth alone renders
    assert load_config("misaligned", image_size=(2, 2), flow_output=True).flow_output


def test_as_int_refuses_a_value_above_its_maximum_giving_the_range():
    from sidar_torch.config import MAX_WORKERS, as_int

    assert as_int("num_workers", np.int64(MAX_WORKERS), 0, MAX_WORKERS) == MAX_WORKERS
    with pytest.raises(ValueError, match=r"^num_workers: expected an integer from 0 to 256, got 257$"):
        as_int("num_workers", 257, 0, MAX_WORKERS)
    with pytest.raises(ValueError, match=r"^count: expected an integer <= 4, got 5$"):
        as_int("count", 5, maximum=4)


def test_a_value_names_the_file_it_came_from_in_a_base_chain(tmp_path):
    (tmp_path / "base.yaml").write_text("base: misaligned\nn_views: 1000\ncamera_xy: 0.5\n")
    (tmp_path / "child.yaml").write_text("base: base.yaml\nn_views: 3\n")
    assert load_config(tmp_path / "child.yaml").n_views == 3  # the base's wrong value is replaced, as before
    (tmp_path / "child.yaml").write_text("base: base.yaml\ncamera_xy: 0.25\n")
    with pytest.raises(ValueError, match=rf"^config file {str(tmp_path / 'base.yaml')!r}: config field 'n_views'"):
        load_config(tmp_path / "child.yaml")
    assert load_config(tmp_path / "child.yaml", n_views=2).n_views == 2


def load_in_a_child(path):
    """stderr of ``load_config(path)`` in a child process given 120 s: a blocking ``open`` of a FIFO
    would never return, however loaded the machine, so the bound only tells a hang from a refusal."""
    result = subprocess.run([sys.executable, "-c", "import sys; from sidar_torch import load_config\n"
                             "load_config(sys.argv[1])", str(path)], capture_output=True, text=True, timeout=120)
    assert result.returncode != 0
    return result.stderr.strip().splitlines()[-1]


@pytest.mark.parametrize("kind", ["fifo", "folder"])
def test_a_fifo_or_a_folder_named_yaml_is_not_a_regular_file_and_nothing_blocks(tmp_path, kind):
    """Issue 34 item 4: a FIFO named ``*.yaml`` was reported as missing."""
    path = tmp_path / "fifo.yaml"
    os.mkfifo(path) if kind == "fifo" else path.mkdir()
    assert load_in_a_child(path) == (f"ValueError: config file {str(path)!r}: not a regular file: expected a regular "
                                     f"file, got a {'FIFO' if kind == 'fifo' else 'folder'}")
    child = tmp_path / "child.yaml"
    child.write_text("base: fifo.yaml\n")
    assert load_in_a_child(child).startswith(f"ValueError: config file {str(path)!r}: not a regular file")


def test_a_missing_file_is_still_file_not_found(tmp_path):
    with pytest.raises(FileNotFoundError, match="mine.yaml' does not exist"):
        load_config(tmp_path / "mine.yaml")
