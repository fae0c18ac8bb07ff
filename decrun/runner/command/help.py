"""``decrun --help`` without composing through Hydra (:func:`fast_help`)."""

from __future__ import annotations

from typing import cast

from omegaconf import DictConfig, OmegaConf

from decrun.runner.job.config import config_dir, load_option


def fast_help() -> str:
    """``decrun --help`` without composing through Hydra (which deep-copies its whole config
    store once per config group): the header, the options of each config group (the YAML
    files of ``conf/``) and the default config (``config.yaml``'s defaults merged in order).
    With overrides (``decrun app=hodge --help``) Hydra's own help runs."""
    root = config_dir()
    main_cfg = OmegaConf.load(root / "config.yaml")
    lines = [str(main_cfg.hydra.help.header).rstrip(), "", "== Configuration groups ==",
             "Compose your configuration from those groups (group=option)", ""]
    for group in sorted(p.name for p in root.iterdir() if p.is_dir() and not p.name.startswith((".", "_"))):
        options = sorted(f.stem for f in (root / group).glob("*.yaml") if not f.stem.startswith("_"))
        if options:
            lines.append(f"{group}: {', '.join(options)}")
    merged = OmegaConf.create()
    for entry in main_cfg.defaults:
        if isinstance(entry, str) or entry is None:
            continue
        for group, option in entry.items():
            if not group.startswith(("override ", "hydra/")):  # Hydra's own groups are not the task's
                merged[group] = load_option(group, option)
    body = {k: v for k, v in cast(dict, OmegaConf.to_container(main_cfg)).items() if k not in ("defaults", "hydra")}
    merged = cast(DictConfig, OmegaConf.merge(merged, body))
    lines += ["", "", "== Config ==", "Override anything in the config (foo.bar=value)", "",
              OmegaConf.to_yaml(merged).rstrip(), "", str(main_cfg.hydra.help.footer).rstrip(), ""]
    return "\n".join(lines)
