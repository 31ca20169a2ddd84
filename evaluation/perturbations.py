"""Perturbations for a run (``mirrorpark evaluate --perturb``): found by name or file, and
recorded in the results folder so that a run never resumes under another perturbation."""

from __future__ import annotations

import json
from pathlib import Path

from mirrorpark_env.config import PERTURB_PRESETS, PerturbConfig, load, perturb_preset

RECORD = "perturb.json"  # in a results folder: the perturbation its rows ran under


def resolve(spec: str | PerturbConfig | None) -> PerturbConfig | None:
    """A preset name (``mild``, ``moderate``, ``severe``), a YAML file of ``PerturbConfig``'s
    fields, a config, or None (unperturbed); ``ValueError`` naming what is allowed."""
    if spec is None or isinstance(spec, PerturbConfig):
        return spec
    if spec in PERTURB_PRESETS:
        return perturb_preset(spec)
    p = Path(spec)
    if p.suffix.lower() in (".yaml", ".yml") and p.is_file():
        return load(PerturbConfig, p)
    raise ValueError(f"--perturb: one of {list(PERTURB_PRESETS)} or a YAML file of perturbation fields, got {spec!r}")


def check_folder(folder: Path, perturb: PerturbConfig | None, rows: int) -> None:
    """Refuse to add rows of ``perturb`` to a folder whose ``rows`` rows ran under another one
    (or unperturbed); record ``perturb`` in a folder that has no rows yet."""
    path = Path(folder) / RECORD
    before = json.loads(path.read_text()) if path.exists() else None
    now = None if perturb is None else perturb.model_dump(mode="json")
    if rows and before != now:
        was = "unperturbed" if before is None else f"perturbation {before.get('name')!r}"
        given = "unperturbed" if now is None else f"perturbation {now['name']!r}"
        raise ValueError(
            f"{folder}: its {rows} rows ran {was}, this run is {given} (or the same name with other values): "
            "resuming would mix them. Run into a fresh --out folder"
        )
    if now is None:
        path.unlink(missing_ok=True)
    else:
        path.write_text(json.dumps(now, indent=1) + "\n")


def of_folder(folder: Path) -> PerturbConfig | None:
    """The perturbation a results folder's rows ran under (None: unperturbed)."""
    path = Path(folder) / RECORD
    return PerturbConfig.model_validate(json.loads(path.read_text())) if path.exists() else None
