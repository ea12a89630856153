"""Campaign specification: a base config, a list of mixtures, and a number of replicas.

A campaign TOML file holds

- ``replicas`` (int >= 1): runs per mixture, with seeds ``seed, seed + 1, ...`` where ``seed`` is
  the resolved config's seed (``base.seed``, or the config default when absent);
- ``[base]``: every run-config key except ``populations`` (``n_particles``, ``lateral_size``,
  ``[base.solver]``, ``[base.equilibrium]``, ...);
- ``[[mixtures]]``: one entry per mixture with

  - ``name`` (required): a folder name (letters, digits, ``.``, ``_``, ``-``), unique;
  - ``family`` and ``share`` (optional): the mixture series and the volume share of the
    substituted grains (0..1) that it stands for, used as the figures' curves and x axes;
  - ``[[mixtures.populations]]`` (required): the run config's populations;
  - any other key **overrides the base key of the same name** for this mixture only (e.g.
    ``lateral_size = 10.0`` or ``[mixtures.solver]``); tables are merged key by key.

Each (mixture, replica) becomes one :class:`RunSpec`, whose run config is checked up front with
:func:`granpack.config.load_config_dict`, so that a typo fails before anything runs.
"""

from __future__ import annotations

import copy
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from granpack.errors import InputError

if TYPE_CHECKING:
    from granpack.config import RunConfig

__all__ = ["CampaignSpec", "MixtureSpec", "RunSpec", "load_campaign", "campaign_from_dict"]

_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")
_TOP_KEYS = ("replicas", "base", "mixtures")
_MIXTURE_META = ("name", "family", "share", "populations")


@dataclass(frozen=True)
class MixtureSpec:
    """One mixture of a campaign.

    Attributes:
        name: folder-safe unique name.
        family: the mixture series (e.g. ``"flat"``), or ``None``.
        share: volume share (0..1) of the substituted grains, or ``None``.
        populations: the run config's ``populations`` tables.
        overrides: base keys replaced (tables merged) for this mixture.
    """

    name: str
    family: str | None
    share: float | None
    populations: list[dict[str, Any]]
    overrides: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class RunSpec:
    """One task of a campaign: a mixture at one seed.

    Attributes:
        mixture: the mixture name.
        family: the mixture's family, or ``None``.
        share: the mixture's share (0..1), or ``None``.
        replica: replica index, 0-based.
        seed: the run's random seed.
        config: the run config, validated: ``load_config_dict(settings)``.
        settings: the run config's keys as the campaign file gives them (base, overrides,
            populations, seed), which a run folder's ``task.json`` records and the warning about
            the flat ``[solver]`` layout of granpack 0.1.0 reads.
    """

    mixture: str
    family: str | None
    share: float | None
    replica: int
    seed: int
    config: RunConfig
    settings: dict[str, Any]

    @property
    def folder(self) -> Path:
        """Run folder relative to the campaign output folder: ``<mixture>/seed-<seed>``."""
        return Path(self.mixture) / f"seed-{self.seed}"

    @property
    def shapes(self) -> str:
        """The population shapes, sorted and joined by ``+`` (e.g. ``"pinacoid"``, ``"sphere"``)."""
        return "+".join(sorted({p.shape for p in self.config.populations}))


@dataclass(frozen=True)
class CampaignSpec:
    """A validated campaign.

    Attributes:
        replicas: runs per mixture.
        base: base run-config keys (no ``populations``).
        mixtures: the mixtures, in file order.
        runs: every (mixture, replica) task, mixture-major order.
        source_text: the TOML text it was read from ('' when built from a dict).
    """

    replicas: int
    base: dict[str, Any]
    mixtures: tuple[MixtureSpec, ...]
    runs: tuple[RunSpec, ...]
    source_text: str = ""


def load_campaign(path: str | Path) -> CampaignSpec:
    """Read and validate a campaign TOML file.

    Args:
        path: the campaign file.

    Returns:
        The validated campaign.

    Raises:
        InputError: unreadable file, bad TOML, an invalid key, or a mixture that no run can pack
            (:func:`granpack.advice.refusal`): one line naming it.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(f"{path}: cannot read campaign file ({exc.strerror or exc})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: invalid TOML ({exc})") from None
    return campaign_from_dict(data, source=str(path), source_text=text)


def _merge(base: dict[str, Any], override: dict[str, Any]) -> dict[str, Any]:
    """``base`` with ``override`` applied; nested tables are merged key by key (new dict)."""
    out = copy.deepcopy(base)
    for key, value in override.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def _mixture(entry: Any, index: int, source: str) -> MixtureSpec:
    where = f"{source}: mixtures[{index}]"
    if not isinstance(entry, dict):
        raise InputError(f"{where} must be a table ([[mixtures]])")
    name = entry.get("name")
    if not isinstance(name, str) or not _NAME.match(name):
        raise InputError(
            f"{where}.name must be a folder name of letters, digits, '.', '_', '-' (got {name!r})"
        )
    where = f"{source}: mixtures[{index}] ({name})"
    family = entry.get("family")
    if family is not None and (not isinstance(family, str) or not family):
        raise InputError(f"{where}.family must be a non-empty string (got {family!r})")
    share = entry.get("share")
    if share is not None:
        if isinstance(share, bool) or not isinstance(share, (int, float)) or not 0.0 <= share <= 1.0:
            raise InputError(f"{where}.share must be a number in [0, 1] (a volume share, got {share!r})")
        share = float(share)
    populations = entry.get("populations")
    if not isinstance(populations, list) or not populations or not all(isinstance(p, dict) for p in populations):
        raise InputError(f"{where}.populations must be a non-empty list of tables ([[mixtures.populations]])")
    if "seed" in entry:
        raise InputError(f"{where}.seed is not allowed: seeds come from base.seed and the replica number")
    overrides = {k: v for k, v in entry.items() if k not in _MIXTURE_META}
    return MixtureSpec(name=name, family=family, share=share, populations=populations, overrides=overrides)


def campaign_from_dict(data: dict[str, Any], *, source: str = "campaign", source_text: str = "") -> CampaignSpec:
    """Validate a campaign given as a parsed TOML dict.

    Args:
        data: the parsed campaign (keys ``replicas``, ``base``, ``mixtures``).
        source: name used in error messages (the file path).
        source_text: the original text, kept for provenance.

    Returns:
        The validated campaign, each run carrying its validated config.

    Raises:
        InputError: one line naming the bad key, e.g. ``study.toml: mixtures[3] (flat-28):
            populations[1].size: ...``.
    """
    unknown = sorted(set(data) - set(_TOP_KEYS))
    if unknown:
        raise InputError(f"{source}: unknown key '{unknown[0]}' (allowed: {', '.join(_TOP_KEYS)})")
    replicas = data.get("replicas", 1)
    if isinstance(replicas, bool) or not isinstance(replicas, int) or replicas < 1:
        raise InputError(f"{source}: replicas must be an integer >= 1 (got {replicas!r})")
    base = data.get("base", {})
    if not isinstance(base, dict):
        raise InputError(f"{source}: base must be a table ([base])")
    if "populations" in base:
        raise InputError(f"{source}: base.populations is not allowed: populations belong to each [[mixtures]] entry")
    entries = data.get("mixtures")
    if not isinstance(entries, list) or not entries:
        raise InputError(f"{source}: mixtures must be a non-empty list of tables ([[mixtures]])")
    mixtures = tuple(_mixture(entry, i, source) for i, entry in enumerate(entries))
    seen: set[str] = set()
    for i, mix in enumerate(mixtures):
        if mix.name in seen:
            raise InputError(f"{source}: mixtures[{i}].name '{mix.name}' is used by an earlier mixture")
        seen.add(mix.name)

    from granpack.advice import refusal  # what no run can pack is refused before any run starts
    from granpack.config import load_config_dict  # the run-config contract (granpack.config)
    from granpack.mixture import Mixture

    runs: list[RunSpec] = []
    for i, mix in enumerate(mixtures):
        merged = _merge(base, mix.overrides)
        merged["populations"] = copy.deepcopy(mix.populations)
        where = f"{source}: mixtures[{i}] ({mix.name})"
        config = load_config_dict(merged, source=where)
        reason = refusal(config, Mixture.from_config(config))
        if reason is not None:
            raise InputError(f"{where}: {reason}")
        for r in range(replicas):
            settings = dict(merged, seed=config.seed + r)
            runs.append(RunSpec(mixture=mix.name, family=mix.family, share=mix.share, replica=r, seed=config.seed + r,
                                config=load_config_dict(settings, source=where), settings=settings))
    return CampaignSpec(replicas=replicas, base=base, mixtures=mixtures, runs=tuple(runs), source_text=source_text)
