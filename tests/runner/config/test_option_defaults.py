"""One home for every option (issue 27 item 7): the default a user gets from the CLI
(conf/<group>/<name>.yaml) is the default of the plugin's dataclass (the Python API), except
for the differences listed in INTENDED, each with its reason."""

from __future__ import annotations

import dataclasses
import importlib

from omegaconf import OmegaConf

from decrun.runner.job.config import PLUGIN_GROUPS, config_dir, load_option

#: (conf file, key): why its YAML default differs from the dataclass default
INTENDED = {
    ("app/fluid.yaml", "initial"): "the CLI's default fluid shows a flow (seeded random vorticity, issue 27.3); "
                                   "Fluid() in Python starts at rest, as the thesis' experiments do",
    ("mesh/file.yaml", "path"): "`???` is OmegaConf's required value: `decrun mesh=file` must be given mesh.path; "
                                "the dataclass' '' is refused by File's check with the same hint",
    ("mesh/annulus.yaml", "refine"): "the CLI refines the one band of triangles twice (midpoint); Annulus() in "
                                     "Python is the raw primitive (refine is MeshSource's post-processing, off)",
    ("mesh/annulus.yaml", "refine_iterations"): "see annulus refine",
    ("mesh/cube.yaml", "refine"): "the CLI Loop-subdivides the 12 triangles twice; Cube() in Python is the raw "
                                  "12-triangle cube (tests/runner/mesh/test_meshes.py builds on it)",
    ("mesh/cube.yaml", "refine_iterations"): "see cube refine",
    ("app/vector_field.yaml", "sources"): "the CLI's null: a source/sink pair from the mesh (issue 27.2), so the "
                                          "default runs on every mesh; in Python a design of strokes or vortices "
                                          "only gets no source it did not ask for (sources=None asks for the pair; "
                                          "tests/apps/test_vector_field.py relies on the empty default)",
    ("mesh/grid_holes.yaml", "nx"): "a preset of Grid (the operator-variant comparison's 25 x 25 grid)",
    ("mesh/grid_holes.yaml", "ny"): "a preset of Grid (the operator-variant comparison's 25 x 25 grid)",
    ("mesh/grid_holes.yaml", "hole_boxes"): "a preset of Grid: its three holes are what makes it grid_holes",
    ("mesh/cow.yaml", "sample"): "a preset of Sample: the sample it names is what makes it cow",
    ("mesh/cow.yaml", "repair"): "a preset of Sample: the modelled cow needs no scan repair (mesh=sample repairs)",
    ("mesh/bunny.yaml", "repair"): "a preset of Sample: the raw scan as it is (its defects are the point); "
                                   "mesh=sample repairs",
    ("mesh/bunny.yaml", "clean"): "a preset of Sample: the raw scan as it is; mesh=sample cleans",
    ("mesh/icosphere_earth.yaml", "radius"): "a preset of Icosphere: the Earth's radius a = 6.37122e6 m of "
                                             "app=shallow_water (Williamson et al. 1992) is what makes it earth",
    ("mesh/icosphere_earth.yaml", "subdiv"): "a preset of Icosphere: app=shallow_water's default resolution "
                                             "(2562 cells), as its dt = 1600 s is chosen for",
    ("mesh/icosphere.yaml", "noise"): "the CLI's icosphere is the default smoothing input (noisy, seeded); "
                                      "Icosphere() in Python is the clean sphere the tests and methods build on",
    ("mesh/planar.yaml", "holes"): "the preset's hole sits inside the preset's unit-square `outer`; a Python "
                                   "caller giving its own outer gets no hole it did not ask for",
}


def _plugin_nodes(node, where):
    """(where, node) of every dict with a `_target_` naming a dataclass, nested ones included."""
    if isinstance(node, dict):
        if "_target_" in node:
            module, _, name = str(node["_target_"]).rpartition(".")
            cls = getattr(importlib.import_module(module), name)
            if dataclasses.is_dataclass(cls):
                yield where, cls, node
            children = {k: v for k, v in node.items() if k != "_target_"}
        else:
            children = node
        for key, value in children.items():
            yield from _plugin_nodes(value, f"{where}.{key}")
    elif isinstance(node, list):
        for i, value in enumerate(node):
            yield from _plugin_nodes(value, f"{where}[{i}]")


def _yaml_defaults():
    """(conf file, dataclass, YAML values) of every plugin node of conf/, each group option
    composed as `decrun <group>=<name>` composes it (its same-group defaults list merged)."""
    root = config_dir()
    for path in sorted(root.rglob("*.yaml")):
        relative = path.relative_to(root)
        group, name = str(relative.parent), path.stem
        if len(relative.parts) == 2 and not name.startswith("_") and group not in ("hydra", "experiment"):
            node = load_option(group, name)
        else:
            node = OmegaConf.load(path)
            node.pop("defaults", None)
        for where, cls, values in _plugin_nodes(OmegaConf.to_container(node, resolve=False), ""):
            yield str(relative) + where, cls, values


#: the options that make a declarative model (decrun/apps/model.py): a model file is data and
#: differs from the dataclass' empty model there by design; its other options come from
#: conf/app/_model.yaml, which equals the dataclass defaults (compared here like any plugin)
MODEL_DATA = {"model", "fields", "constants", "equations", "metrics", "integrator", "dt", "t_end", "steps",
              "record_every", "snapshots", "animation", "seed", "parts", "plots", "require"}


def differences():
    from decrun.apps.model import Model

    found = {}
    for where, cls, values in _yaml_defaults():
        schema = OmegaConf.structured(cls)
        for key, value in values.items():
            if key == "_target_" or (isinstance(value, dict) and "_target_" in value):
                continue
            if cls is Model and key in MODEL_DATA and not where.startswith("app/_model.yaml"):
                continue
            assert key in schema, f"{where}: {key} is not an option of {cls.__name__}"
            default = OmegaConf.to_container(schema, enum_to_str=True)[key]
            given = value if value == "???" else OmegaConf.to_container(  # as the schema types it (enums, nested dataclasses)
                OmegaConf.merge(schema, {key: value}), enum_to_str=True)[key]
            if given != default:
                found[(where, key)] = (value, default)
    return found


def test_walk_sees_every_group_option():
    """The walk reaches the plugin nodes of every group (a broken walk must not pass vacuously)."""
    files = {where.split("/")[0] for where, _, _ in _yaml_defaults()}
    assert set(PLUGIN_GROUPS) <= files
    assert sum(len(values) for _, _, values in _yaml_defaults()) > 140


def test_yaml_defaults_equal_dataclass_defaults():
    found = differences()
    unexpected = {k: v for k, v in found.items() if k not in INTENDED}
    assert not unexpected, "YAML default != dataclass default (make them equal or list it in INTENDED): " + "; ".join(
        f"{where} {key}: yaml {y!r} vs dataclass {d!r}" for (where, key), (y, d) in unexpected.items())
    stale = set(INTENDED) - set(found)
    assert not stale, f"INTENDED lists differences that are gone: {sorted(stale)}"

