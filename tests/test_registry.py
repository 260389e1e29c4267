"""The generic registry: registration, kinds, module:factory targets and entry points."""

import sys
import textwrap
import warnings

import pytest

from evedge.registry import Entry, Registry, RegistryError, resolve_target


def test_register_get_names_and_kinds():
    reg = Registry("widget", kinds=("round", "square"))
    reg.register("disc", lambda r=1.0: ("disc", r), kind="round", display_name="a disc", colour="#123456", sides=0)
    @reg.register("box", kind="square")
    def box():
        return "box"
    assert box() == "box"  # the decorator returns the function itself
    assert reg.names() == ("disc", "box")
    assert reg.names(kind="square") == ("box",)
    e = reg.get("disc")
    assert (e.display_name, e.colour, e.metadata, e.source) == ("a disc", "#123456", {"sides": 0}, "builtin")
    assert reg.get("box").display_name == "box" and reg.get("box").colour.startswith("#")
    assert "disc" in reg and "nope" not in reg and len(reg) == 2
    with pytest.raises(RegistryError, match="unknown widget 'nope'; registered: disc, box"):
        reg.get("nope")
    with pytest.raises(RegistryError, match="is of kind 'round', not 'square'"):
        reg.get("disc", kind="square")
    with pytest.raises(ValueError, match="already registered"):
        reg.register("disc", lambda: 0, kind="round")
    with pytest.raises(ValueError, match="kind must be one of"):
        reg.register("tri", lambda: 0, kind="triangle")
    with pytest.raises(ValueError, match="without ':'"):
        reg.register("a:b", lambda: 0, kind="round")


def test_module_factory_targets(tmp_path, monkeypatch):
    pkg = tmp_path / "plugpkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "m.py").write_text(textwrap.dedent("""
        class Thing:
            kind = "round"
            display_name = "a plug-in thing"
        def no_kind():
            pass
        NOT_CALLABLE = 3
    """))
    monkeypatch.syspath_prepend(str(tmp_path))
    reg = Registry("widget", kinds=("round", "square"))
    e = reg.get("plugpkg.m:Thing")
    assert (e.kind, e.display_name, e.source) == ("round", "a plug-in thing", "module:factory")
    assert reg.get("plugpkg.m:Thing") is e  # registered under its target on first use
    with pytest.raises(RegistryError, match="no 'kind' attribute"):
        reg.get("plugpkg.m:no_kind")
    with pytest.raises(RegistryError, match="expected a factory"):
        reg.get("plugpkg.m:NOT_CALLABLE")
    with pytest.raises(RegistryError, match="cannot import module 'plugpkg.absent'"):
        reg.get("plugpkg.absent:X")
    with pytest.raises(RegistryError, match="has no attribute 'Missing'"):
        reg.get("plugpkg.m:Missing")
    with pytest.raises(RegistryError, match="not of the form"):
        resolve_target("not a target")
    assert resolve_target("os.path:join") is __import__("os").path.join


def test_entry_points_are_read(tmp_path, monkeypatch):
    # a minimal installed distribution with an entry point in the group
    site = tmp_path / "site"
    (site / "epplug").mkdir(parents=True)
    (site / "epplug" / "__init__.py").write_text("class Est:\n    kind = 'round'\n    display_name = 'from ep'\n")
    dist = site / "epplug-1.0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: epplug\nVersion: 1.0\n")
    (dist / "entry_points.txt").write_text("[test.widgets]\nepthing = epplug:Est\nbroken = epplug:Missing\n")
    monkeypatch.syspath_prepend(str(site))
    reg = Registry("widget", kinds=("round",), entry_point_group="test.widgets")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        names = reg.names()
    assert names == ("epthing",)
    assert reg.get("epthing").display_name == "from ep"
    assert reg.get("epthing").source == "entry point epplug:Est"
    assert any("broken" in str(w.message) for w in caught)  # a broken plug-in is reported, not fatal
    sys.modules.pop("epplug", None)


def test_builtin_methods_are_registered_once():
    from evedge.detector.protocols import METHODS

    assert {"intra", "mueggler", "time", "count", "buffer"} <= set(METHODS.names())
    assert METHODS.names(kind="estimator")[:2] == ("intra", "mueggler")
    assert METHODS.names(kind="filter")[0] == "buffer"
    assert set(METHODS.names(kind="edges")) >= {"time", "count"}
    assert isinstance(METHODS.get("intra"), Entry)
    assert METHODS.get("intra").metadata["filter"] == "buffer"
    assert METHODS.get("mueggler").metadata["filter"] is None
    assert len({e.colour for e in METHODS.entries()}) == len(METHODS.entries())
