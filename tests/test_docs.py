"""The docs match the code: the API reference lists every public name, the README points in."""

import re
import sys
from pathlib import Path

import nextage_qp
from nextage_qp import api, errors

ROOT = Path(__file__).resolve().parents[1]


def test_api_reference_covers_every_public_name() -> None:
    text = (ROOT / "docs" / "api.md").read_text()
    listed = set(re.findall(r"[A-Za-z_]+", " ".join(re.findall(r"members: \[([^\]]*)\]", text))))
    assert set(api.__all__) <= listed, set(api.__all__) - listed
    assert "::: nextage_qp.errors" in text  # every error class, the whole module
    exported = set(nextage_qp.__all__)
    documented = listed | {n for n in dir(errors) if isinstance(getattr(errors, n), type)}
    documented |= {name for name in ("Robot", "SceneOverrides") if re.search(rf"::: nextage_qp\.[\w.]+\.{name}\b", text)}
    missing = exported - documented
    assert not missing, missing


def test_every_docs_page_is_in_the_site_and_every_example_is_listed() -> None:
    nav = (ROOT / "mkdocs.yml").read_text()
    for page in (ROOT / "docs").glob("*.md"):
        assert page.name in nav, page.name
    listed = (ROOT / "docs" / "examples.md").read_text()
    for script in (ROOT / "examples").glob("*.py"):
        assert f"examples/{script.name}" in listed, script.name


def test_readme_leads_to_the_docs() -> None:
    lines = (ROOT / "README.md").read_text().splitlines()
    first_screen = "\n".join(lines[:40])
    assert "pip install" in first_screen and "pytest" in first_screen  # install and test
    assert "| task |" in first_screen or "| task" in first_screen  # the results table
    assert "docs/tasks.md" in first_screen  # write your own task


def test_the_config_reference_is_generated_from_the_schemas_and_complete() -> None:
    """Every key of every schema has a meaning and, holding numbers, a unit; docs/configs.md is what they give."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("config_reference", ROOT / "tools" / "config_reference.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["config_reference"] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    assert module.problems() == []
    assert (ROOT / "docs" / "configs.md").read_text() == module.render(), "run: python tools/config_reference.py"
    keys = [r.key for _, _, rows in module.sections() for r in rows]
    assert len(keys) > 300 and "phases[].attempts" in keys and "ik.limit_margin" in keys and "phases[].blind" in keys


def test_the_example_outputs_of_getting_started_are_what_the_runs_print() -> None:
    """The JSON shown for the default push and dock is checked field by field against the runs (to its digits)."""
    import json

    from nextage_qp.manipulation.config import load_config
    from nextage_qp.manipulation.runner import Runner

    text = (ROOT / "docs" / "getting-started.md").read_text()
    blocks = re.findall(r"nextage-qp run (configs/\S+\.yaml) --json[^\n]*\n```\n(?:.*?\n)??```json\n(.*?)\n```", text,
                        re.S)
    assert [c for c, _ in blocks] == ["configs/push_cube.yaml", "configs/dock_dumbbell.yaml"]

    def same(shown, actual) -> bool:
        if isinstance(shown, dict):
            return all(same(v, actual[k]) for k, v in shown.items())
        if isinstance(shown, list):
            return len(shown) == len(actual) and all(same(s, a) for s, a in zip(shown, actual, strict=True))
        if isinstance(shown, float):
            digits = len(repr(shown).split("e")[0].replace("-", "").replace(".", "").lstrip("0"))
            return f"{actual:.{max(digits, 1)}g}" == f"{shown:.{max(digits, 1)}g}"
        return shown == actual

    for config, block in blocks:
        shown = json.loads(block)
        record = Runner(load_config(ROOT / config), config).run().record
        assert same(shown, record), (config, shown, {k: record[k] for k in shown})
