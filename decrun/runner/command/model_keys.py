"""Every documented option of a declarative model, overridable in any model file.

A model file that does not start from ``conf/app/_model.yaml`` (``defaults: [_model, …]``) —
the first model a user writes often lacks it — holds only the options it sets, and Hydra
refuses ``app.steps=3`` for a key the file lacks ("not in struct"). The model's schema
(:class:`decrun.apps.model.Model`) gives every missing option its default when the app is
built, so such an override only needs Hydra's ``+`` form: :func:`with_model_options` rewrites
it so before Hydra composes the command, for the documented options (the keys of
``conf/app/_model.yaml``) of a model that lacks them — a model on a config directory the
command adds with ``hydra.searchpath`` (decrun's own all start from ``_model``). Anything else — a misspelt option
(``app.stpes=3``), another app — is left to Hydra and decrun's one-line errors."""

from __future__ import annotations

from omegaconf import OmegaConf

from decrun.runner.job.config import config_dir

__all__ = ["MODEL_TARGET", "documented_options", "with_model_options", "refuse_unread_constants"]

#: the ``_target_`` of a declarative model's config
MODEL_TARGET = "decrun.apps.model.Model"


def documented_options() -> set[str]:
    """The options of ``conf/app/_model.yaml`` (every option of a model, with its default)."""
    node = OmegaConf.load(config_dir() / "app" / "_model.yaml")
    return {str(key) for key in node if key != "_target_"}


def _option(arg: str, options: set[str]) -> str | None:
    """The documented model option a plain ``app.<option>…=value`` override sets, else None."""
    name, sep, _ = arg.partition("=")
    if not sep or not name.startswith("app."):  # +app.…, ++app.…, ~app.…: as given
        return None
    option = name.split(".")[1]
    return option if option in options else None


def with_model_options(args: list[str]) -> list[str]:
    """``args`` (a ``decrun`` command line) with each override ``app.<option>…=value`` of a
    documented model option that the chosen model's file lacks written ``+app.<option>…=value``
    (the schema's default is then overridden, as in a model starting from ``_model``). ``args``
    unchanged when there is none, or when the command's config cannot be composed (Hydra
    then reports why)."""
    options = documented_options()
    if not any(_option(arg, options) for arg in args):
        return args
    if not any(arg.lstrip("+").startswith("hydra.searchpath=") for arg in args):
        return args  # decrun's own models start from _model (tests/runner/test_model_day_one.py): nothing to compose
    choices = []  # the command's group choices, experiments and search path: what picks the model file
    for arg in args:
        name, sep, _ = arg.partition("=")
        bare = name.lstrip("+~")
        if sep and (bare == "hydra.searchpath" or ("." not in bare and not bare.startswith("hydra"))):
            choices.append(arg.split(",")[0] if bare != "hydra.searchpath" else arg)
    from decrun.runner.job.config import compose_config

    try:
        app = compose_config(choices).app
        target, present = app.get("_target_"), set(app.keys())
    except Exception:  # noqa: BLE001 — not composable this way: Hydra reports the command as given
        return args
    if target != MODEL_TARGET:
        return args
    missing = options - present
    return [f"+{arg}" if _option(arg, missing) else arg for arg in args]


def refuse_unread_constants(args: list[str]) -> None:
    """For ``+app.constants.<name>=…`` on the command line (Hydra's advice for a constant the
    model does not have, ``+app.constants.epz=0.1``): ConfigError when nothing in the model reads
    ``<name>`` (:func:`decrun.runner.job.model_checks.check_model`), naming the closest constant
    that is read. Nothing when there is no such override or the command cannot be composed this
    way (Hydra then reports why)."""
    added = [arg.partition("=")[0].split(".")[2] for arg in args
             if arg.startswith("+app.constants.") and arg.partition("=")[0].count(".") == 2]
    if not added:
        return
    overrides = []  # the command's config, a sweep's first values
    for arg in args:
        name, sep, value = arg.partition("=")
        bare = name.lstrip("+~")
        if not sep or (bare.startswith(("hydra.", "hydra/")) and bare != "hydra.searchpath"):
            continue
        overrides.append(arg if bare == "hydra.searchpath" else f"{name}={value.split(',')[0]}")
    from decrun.errors import DecrunError
    from decrun.runner.job.config import compose_config
    from decrun.runner.job.experiment import validate  # lazy: the numerical stack (start-up speed)
    from decrun.runner.job.model_checks import check_model

    try:
        app = validate(compose_config(overrides)).app
    except DecrunError:
        raise
    except Exception:  # noqa: BLE001 — not composable this way: Hydra reports the command as given
        return
    from decrun.apps.model import Model

    if isinstance(app, Model):
        check_model(app, added)
