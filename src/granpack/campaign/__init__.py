"""Campaigns: many packings (mixtures x replicas) run as Dask tasks, collected into tables.

- :mod:`~granpack.campaign.spec`: the campaign TOML (base config, mixtures, replicas) -> tasks;
- :mod:`~granpack.campaign.runner`: the tasks on a local or remote Dask cluster, resumable;
- :mod:`~granpack.campaign.store`: run-folder state and the ``runs.csv`` / ``runs.parquet`` /
  ``summary.csv`` tables.
"""

from __future__ import annotations

from granpack.campaign.runner import CampaignReport, run_campaign
from granpack.campaign.spec import CampaignSpec, MixtureSpec, RunSpec, campaign_from_dict, load_campaign

__all__ = [
    "CampaignReport",
    "CampaignSpec",
    "MixtureSpec",
    "RunSpec",
    "campaign_from_dict",
    "load_campaign",
    "run_campaign",
]
