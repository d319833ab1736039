import json

import pytest

from bdft import main


@pytest.fixture(scope="module")
def computed_once():
    """The reproduction computed once per set of variants for the module's command runs.

    Both runs below ask for the literal human: the first computes it through the real
    :func:`reports.reproduce.reproduce`, the other gets that result (the report writing,
    where the failure test breaks in, runs in each).
    """
    import importlib

    rr = importlib.import_module("reports.reproduce")  # (reports.reproduce is also a function)

    real, done = rr.reproduce, {}

    def once(*, variants, progress=None, **kw):
        if kw:  # (the command passes nothing else)
            return real(variants=variants, progress=progress, **kw)
        key = tuple(variants)
        if key not in done:
            done[key] = real(variants=variants, progress=progress)
        return done[key]

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(rr, "reproduce", once)
        yield done


def test_reproduce_json_end_to_end(tmp_path, capsys, computed_once):
    out = tmp_path / "reproduce"
    code = main(["reproduce", "--out", str(out), "--human", "literal", "--json"])
    assert code == 0
    obj = json.loads(capsys.readouterr().out)
    for key in ("C1", "C2", "C3"):
        assert obj["claims"][key]["holds"] is True, obj["claims"][key]["detail"]
    assert obj["claims"]["C4"]["holds"] is False
    assert set(obj["claims"]) == {"C1", "C2", "C3", "C4", "C5"}
    cal = obj["calibration"]
    assert cal["search_matches_default"] is True
    assert {"kp", "ki", "loop_scale", "handle_sign"} <= set(cal)
    html = (out / "index.html").read_text()
    # every figure the page references exists and is a PNG
    import re

    imgs = re.findall(r'src="([^"]+\.png)"', html)
    assert len(imgs) >= 7
    for name in imgs:
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert json.loads((out / "claims.json").read_text())["claims"]["C1"]["holds"] is True
    # no temporary folders left beside the report
    assert [p.name for p in tmp_path.iterdir()] == ["reproduce"]


def test_reproduce_failure_leaves_nothing(tmp_path, monkeypatch, capsys, computed_once):
    import reports.figures as plots

    def boom(*a, **k):
        raise RuntimeError("figure failed")

    monkeypatch.setattr(plots, "ratio_figure", boom)
    logs = tmp_path / "logs"
    logs.mkdir()
    monkeypatch.setenv("BDFT_LOG_DIR", str(logs))
    out = tmp_path / "work" / "reproduce"
    out.parent.mkdir()
    # an unexpected error: exit code 1, one line naming the traceback file
    assert main(["reproduce", "--out", str(out), "--human", "literal"]) == 1
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith("bdft reproduce: internal error: RuntimeError: figure failed")
    log = next(logs.iterdir())
    assert str(log) in err and "figure failed" in log.read_text()
    assert list(out.parent.iterdir()) == []


def test_unknown_human_variant_is_rejected(capsys):
    assert main(["reproduce", "--human", "robot"]) == 2
    assert "bdft reproduce: error: --human: expected one of" in capsys.readouterr().err
