"""The README's Python block runs as written (from the repository's root) and converges as the tutorial says."""

import re


def test_the_readme_python_loop_runs_and_converges(repo, monkeypatch):
    readme = (repo / "README.md").read_text()
    (block,) = re.findall(r"```python\n(.*?)```", readme, flags=re.S)
    monkeypatch.chdir(repo)
    names = {}
    exec(compile(block, "README.md", "exec"), names)
    assert names["servo"].converged
    assert names["k"] + 1 == 2777  # docs/paper_experiment.md: the full method converges at 2777
