"""pilerl's Hydra launcher on Ray: each sweep job runs as a Ray task.

``hydra/launcher=ray`` (schema ``config.RayLauncherConf``; the project's presets are
``conf/hydra/launcher/ray_local.yaml`` and ``ray_cluster.yaml``). Jobs run where Ray
places them: on a local Ray instance this launcher starts, or on a running cluster
(``address``). See docs/ray.md.

Why not Hydra's official ``hydra-ray-launcher``: its last release (1.2.2) accepts Ray 2.58
(``ray[default]<3``) but requires ``cloudpickle<3``, while ``joblib`` 1.6 (used by
``hydra-joblib-launcher`` and scikit-learn) requires ``cloudpickle>=3.0``; pip reports
``ResolutionImpossible`` for ``hydra-ray-launcher==1.2.2`` with ``joblib==1.6.0`` and
resolves only by downgrading joblib to 1.5.3 and cloudpickle to 2.2.1 (checked
2026-11-24, docs/ray.md). Older releases pin ``ray==1.12.0`` / ``ray==1.3.0``, which have
no Python 3.11 wheels.
This launcher follows Hydra's joblib launcher (``Launcher.setup`` / ``launch``,
``Singleton`` state shipped to each job, ``run_job``, ``JobReturn`` in order) and needs
only ``ray`` itself; the official plugin's AWS autoscaling mode is left out.

Hydra imports this package's public modules at every start to find plugins, so they
import neither Ray nor pilerl; ``_core`` does, when a sweep is launched.
"""
