"""The hostile-input contract held by a seeded mutation fuzzer (tests/fuzz.py): each mutant of a
shipped stage renders with finite pixels or exits 2 with one error line and no output."""


import pytest
from fuzz import judge, mutants, render_args

from warp_blur.tools.cli import main

SEED = 20261202
COUNT = 28   # every shipped stage under every method; `python tests/fuzz.py --many N` soaks


@pytest.mark.parametrize("index", range(COUNT))
def test_mutant_keeps_the_contract(tmp_path, capsys, index):
    """Every fourth mutant renders with --skip-invalid: the contract holds where invalid prims are
    dropped (and a frame is rendered again without one found invalid mid-shutter) too."""
    i, name, method, data, kind = list(mutants(index + 1, SEED))[index]
    scene = tmp_path / f"{name}.usda"
    scene.write_bytes(data)
    out = str(tmp_path / "out.exr")
    code = main(render_args(str(scene), out, method, skip_invalid=index % 4 == 3))
    err = capsys.readouterr().err
    verdict = judge(code, err, out)
    assert verdict.startswith("ok"), f"{verdict} ({name}, {method}, {kind}): {err[-400:]}"
