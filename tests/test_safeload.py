"""Reading data anyone may have written (bsrbench.safeload): plain values, bounded size, nesting and aliases."""

from pathlib import Path

import pytest
import yaml

from bsrbench.errors import DataFileError, InputError
from bsrbench.safeload import MAX_NODES, check_plain, json_text, read_yaml, yaml_text

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize(
    "path",
    sorted(
        p.relative_to(ROOT).as_posix()
        for p in [*ROOT.glob("config/*.yaml"), *ROOT.glob("profiles/*/*.yaml")]
    ),
)
def test_every_configuration_of_the_project_reads_as_yamls_safe_loader_reads_it(path):
    assert read_yaml(ROOT / path) == yaml.safe_load((ROOT / path).read_text())


def _bomb(levels, width=10):
    lines = ["a0: &a0 [" + ",".join(['"x"'] * width) + "]"]
    for k in range(1, levels):
        lines.append(f"a{k}: &a{k} [" + ",".join([f"*a{k - 1}"] * width) + "]")
    return "\n".join(lines) + "\n"


def test_aliases_count_at_each_use_and_a_bomb_is_refused():
    # 10 + 10 * 11 + 10 * 111 + ... : the expanded size counted by hand for 3 levels
    data = yaml_text(_bomb(3), "small")
    assert data["a2"][0] is data["a2"][1]  # shared, not copied
    sizes = {"a0": 1 + 10, "a1": 1 + 10 * 11, "a2": 1 + 10 * (1 + 10 * 11)}
    assert 1 + sum(1 + s for s in sizes.values()) < MAX_NODES
    with pytest.raises(InputError, match=r"^big: expands to more than 100000 values"):
        yaml_text(_bomb(7), "big")
    with pytest.raises(InputError, match="expands to more than 1000 values"):
        check_plain(yaml.safe_load(_bomb(3)), "x", max_nodes=1000)
    assert check_plain(
        yaml.safe_load(_bomb(3)), "x", max_nodes=1 + sum(1 + s for s in sizes.values())
    )


def test_a_recursive_alias_and_deep_nesting_are_refused():
    with pytest.raises(InputError, match="contains itself"):
        yaml_text("a: &a [1, *a]\n", "rec")
    with pytest.raises(InputError, match="nested more than 32 levels"):
        yaml_text("a: " + "[" * 40 + "]" * 40 + "\n", "deep")
    with pytest.raises(InputError, match="^deeper:"):
        yaml_text("a: " + "[" * 100000 + "]" * 100000 + "\n", "deeper")


def test_a_yte_template_is_refused(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("__use_yte__: true\nx: ?1 + 1\n")
    with pytest.raises(DataFileError, match=r"key '__use_yte__' asks Snakemake to evaluate"):
        read_yaml(path)


def test_a_python_tag_builds_nothing():
    with pytest.raises(InputError, match="not valid YAML"):
        yaml_text("x: !!python/object/apply:os.system ['true']\n", "tag")


def test_size_and_encoding_are_checked(tmp_path):
    big = tmp_path / "big.yaml"
    big.write_text("x: " + "y" * (1 << 20) + "\n")
    with pytest.raises(DataFileError, match="larger than 1048576 bytes"):
        read_yaml(big)
    binary = tmp_path / "bin.yaml"
    binary.write_bytes(b"\x00\xff: [")
    with pytest.raises(DataFileError, match="not UTF-8 text"):
        read_yaml(binary)


def test_json_nesting_and_type_are_bounded():
    assert json_text('{"a": [1, {"b": 2}]}', "ok") == {"a": [1, {"b": 2}]}
    with pytest.raises(InputError, match="JSON nested too deeply"):
        json_text("[" * 100000 + "]" * 100000, "deep")
    with pytest.raises(InputError, match="nested more than 3 levels"):
        json_text("[[[[[1]]]]]", "d", max_depth=3)
    with pytest.raises(InputError, match="of type float; expected JSON text"):
        json_text(5.0, "num")
    with pytest.raises(InputError, match="is not JSON"):
        json_text("{x", "bad")
