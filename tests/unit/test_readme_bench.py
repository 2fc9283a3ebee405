"""The "Measured" table (docs/benchmarks.md, linked from the README) is generated from bench/results
(scripts/gen_readme_bench.py) and names the commit each figure was measured at; a results file older than the last
change to its inputs is reported stale."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.unit


def _generator():  # noqa: ANN202
    spec = importlib.util.spec_from_file_location("gen_readme_bench", ROOT / "scripts" / "gen_readme_bench.py")
    assert spec is not None
    assert spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["gen_readme_bench"] = mod
    spec.loader.exec_module(mod)
    return mod


gen = _generator()


def test_readme_table_matches_results_files() -> None:
    """Fails when bench/results and docs/benchmarks.md disagree (fix: python scripts/gen_readme_bench.py)."""
    assert gen.TABLE_FILE == "docs/benchmarks.md"
    page = (ROOT / gen.TABLE_FILE).read_text(encoding="utf-8")
    results = gen.load(ROOT)
    assert results, "no bench/results/*.txt"
    assert gen.render(page, results) == page, (
        "docs/benchmarks.md's Measured table is out of date: run scripts/gen_readme_bench.py"
    )
    # the table is in one place only, and the README points at it
    assert gen.BEGIN not in (ROOT / "README.md").read_text(encoding="utf-8")
    assert "docs/benchmarks.md" in (ROOT / "README.md").read_text(encoding="utf-8")


def test_every_row_names_its_commit() -> None:
    page = (ROOT / gen.TABLE_FILE).read_text(encoding="utf-8")
    block = page[page.index(gen.BEGIN) + len(gen.BEGIN) : page.index(gen.END)]
    rows = [line for line in block.strip().splitlines()[2:]]
    assert rows
    for r in gen.load(ROOT):
        for line in (x for x in rows if f"| `{r.name}` |" in x):
            assert (f"`{r.commit[:10]}`" in line) if r.commit else ("not recorded" in line), line


def _git(repo: Path, *args: str) -> str:
    env = {"GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t", "GIT_COMMITTER_NAME": "t", "GIT_COMMITTER_EMAIL": "t@t"}
    out = subprocess.run(["git", "-C", str(repo), *args], capture_output=True, text=True, check=True, env=env)
    return out.stdout.strip()


def _results_file(commit: str, tree: str, rows: list[dict[str, object]], inputs: str = "src/node.py") -> str:
    lines = [
        "# python bench/bench_x.py",
        f"# commit: {commit} {tree}",
        "# 2026-01-01T00:00:00Z, 2 cores, load average 0.10 0.20 0.30, Python 3.11.7",
    ]
    lines += ["some human-readable output", f"BENCH-INPUTS {inputs} bench/bench_x.py"]
    lines += ["README-ROW " + json.dumps(r, ensure_ascii=False) for r in rows]
    return "\n".join(lines) + "\n"


@pytest.fixture
def repo(tmp_path: Path) -> Path:
    """A git repository shaped like ours: the table's page with the markers, scripts/bench's default list, a source
    file."""
    (tmp_path / "src").mkdir()
    (tmp_path / "src" / "node.py").write_text("x = 1\n")
    (tmp_path / "src" / "other.py").write_text("y = 1\n")
    (tmp_path / "scripts").mkdir()
    (tmp_path / "scripts" / "bench").write_text("names=(x)\n")
    (tmp_path / "bench" / "results").mkdir(parents=True)
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "benchmarks.md").write_text(f"# t\n\n{gen.BEGIN}\n{gen.END}\n\nafter\n")
    _git(tmp_path, "init", "-q")
    _git(tmp_path, "add", "-A")
    _git(tmp_path, "commit", "-q", "-m", "one")
    return tmp_path


def test_the_machine_s_cpu_is_shown_when_the_results_file_names_it(repo: Path) -> None:
    head = _git(repo, "rev-parse", "HEAD")
    text = _results_file(head, "clean", [{"what": "speed", "figure": "3 ms"}]).replace(
        "Python 3.11.7", "Python 3.11.7, CPU: AMD EPYC at 2596.126 MHz"
    )
    (repo / "bench" / "results" / "x.txt").write_text(text)
    assert gen.main(["--root", str(repo)]) == 0
    readme = (repo / "docs" / "benchmarks.md").read_text()
    assert f"| speed | 3 ms | — | `x` | `{head[:10]}`, load 0.10, AMD EPYC 2.6 GHz |" in readme


def test_generator_writes_rows_with_commit_and_target_verdict(repo: Path) -> None:
    head = _git(repo, "rev-parse", "HEAD")
    rows = [
        {"what": "speed", "figure": "3 | 4 ms", "target": "≤ 5 ms", "ok": True},
        {"what": "rate", "figure": "9 Hz", "target": "≥ 20 Hz", "ok": False},
    ]
    (repo / "bench" / "results" / "x.txt").write_text(_results_file(head, "clean", rows))
    assert gen.main(["--root", str(repo), "--check"]) == 1  # the page does not have the rows yet
    assert gen.main(["--root", str(repo)]) == 0
    text = (repo / "docs" / "benchmarks.md").read_text()
    assert f"| speed | 3 \\| 4 ms | ≤ 5 ms | `x` | `{head[:10]}`, load 0.10 |" in text
    assert "| rate | 9 Hz **(misses the target)** | ≥ 20 Hz |" in text
    assert text.endswith(f"{gen.END}\n\nafter\n")
    assert gen.main(["--root", str(repo), "--check"]) == 0
    assert gen.main(["--root", str(repo), "--check", "--strict"]) == 0  # fresh and clean: no warning


def test_stale_results_are_reported(repo: Path, capsys: pytest.CaptureFixture[str]) -> None:
    measured = _git(repo, "rev-parse", "HEAD")
    (repo / "bench" / "results" / "x.txt").write_text(_results_file(measured, "clean", [{"what": "a", "figure": "1"}]))
    assert gen.main(["--root", str(repo)]) == 0
    _git(repo, "add", "-A")
    _git(repo, "commit", "-q", "-m", "results")
    # A change outside the bench's inputs does not make it stale ...
    (repo / "src" / "other.py").write_text("y = 2\n")
    _git(repo, "commit", "-q", "-am", "unrelated change")
    capsys.readouterr()
    assert gen.main(["--root", str(repo), "--check", "--strict"]) == 0
    assert "STALE" not in capsys.readouterr().err
    # ... a change to one of them does.
    (repo / "src" / "node.py").write_text("x = 2\n")
    _git(repo, "commit", "-q", "-am", "faster node")
    [r] = gen.load(repo)
    assert [line.split(" ", 1)[1] for line in r.stale_by] == ["faster node"]
    assert gen.main(["--root", str(repo), "--check"]) == 0  # the table itself still matches its files
    assert "STALE" in capsys.readouterr().err
    assert gen.main(["--root", str(repo), "--check", "--strict"]) == 1


def test_dirty_unknown_and_missing_commit_are_flagged(repo: Path, capsys: pytest.CaptureFixture[str]) -> None:
    head = _git(repo, "rev-parse", "HEAD")
    res = repo / "bench" / "results"
    (res / "x.txt").write_text(_results_file(head, "dirty", [{"what": "a", "figure": "1"}]))
    (res / "y.txt").write_text(_results_file("0" * 40, "clean", [{"what": "b", "figure": "2"}]))
    (res / "z.txt").write_text("# python bench/bench_z.py\n# 2026-01-01T00:00:00Z, 2 cores, Python 3.11.7\nz 3\n")
    assert gen.main(["--root", str(repo)]) == 0
    err = capsys.readouterr().err
    assert "x.txt: measured with uncommitted changes" in err
    assert "y.txt: measured at 0000000000, which is not in this repository's history" in err
    assert "z.txt: no '# commit:' header" in err
    assert "z.txt: no README-ROW lines" in err
    text = (repo / "docs" / "benchmarks.md").read_text()
    assert f"`{head[:10]}` + uncommitted changes" in text
    assert "| `z`: no figures |" in text
    assert "not recorded" in text
    # table order: scripts/bench's default list first (x), then the rest by name
    assert text.index("| a |") < text.index("| b |") < text.index("`z`: no figures")
    assert gen.main(["--root", str(repo), "--check", "--strict"]) == 1


def test_malformed_row_is_an_error(repo: Path) -> None:
    (repo / "bench" / "results" / "x.txt").write_text("README-ROW " + json.dumps({"what": "no figure"}) + "\n")
    with pytest.raises(ValueError, match="malformed README-ROW"):
        gen.load(repo)


def test_bench_report_lines_round_trip(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """bench/report.py prints exactly what the generator parses."""
    spec = importlib.util.spec_from_file_location("bench_report", ROOT / "bench" / "report.py")
    assert spec is not None
    assert spec.loader is not None
    report = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(report)
    report.inputs("a/b.py", "c")
    report.row("what × 2", "1.0 ms", "≤ 2 ms", True)
    f = tmp_path / "n.txt"
    f.write_text("# cmd\n# commit: abc clean\n" + capsys.readouterr().out)
    r = gen.parse(f)
    assert r.inputs == ("a/b.py", "c")
    assert r.rows == [{"what": "what × 2", "figure": "1.0 ms", "target": "≤ 2 ms", "ok": True}]
    assert (r.commit, r.dirty, r.command) == ("abc", False, "cmd")
