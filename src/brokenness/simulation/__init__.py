"""Synthetic broken maps of known degree: buildings, a simulated laser, a mapper, bump noise.

- :mod:`.building`: seeded floor plans (rooms, corridors, doors, clutter, slanted walls);
- :mod:`.laser`: scan poses along a building's route, ray casting, range and pose noise;
- :mod:`.mapper`: a vectorised log-odds occupancy-grid mapper for 2D laser scans;
- :mod:`.bumps`: the paper's bump noise on the pose estimate (and an exact "k bumps" mode);
- :mod:`.options`: :class:`BumpOptions`, the bump model of a broken map and the honest rule
  (:class:`HonestRule`) that judges its partitions;
- :mod:`.ground_truth`: a run's reference, its broken map, the partitions' true transforms and
  the honest expected degree;
- :mod:`.synthetic`: :func:`simulate_broken_map`, a broken map + reference + ground truth;
- :mod:`.views`: a run mapped in its own frame, cropped; a building's plan as a reference;
- :mod:`.plan_run`: a tour planned through any map or floor plan, scanned (broken maps of
  a building that is known only as a map);
- :mod:`.output`: :func:`save_simulation`, maps (ROS YAML + PGM), ground-truth JSON, labels.
"""

from __future__ import annotations

from .building import Building, generate_building
from .bumps import Bump, apply_bumps, draw_bumps, draw_k_bumps
from .laser import Laser, LaserRun, cast_rays, route_poses, simulate_run
from .mapper import ScanCounts, counts_to_map, grid_geometry, map_prefixes, map_scans, scan_counts
from .options import BumpOptions, HonestRule
from .output import save_simulation
from .plan_run import broken_plan_map, plan_route, simulate_plan_run
from .synthetic import SimulatedMap, SimulatedPartition, simulate_broken_map
from .views import frame_truth, map_in_frame, plan_map

__all__ = [
    "Building",
    "Bump",
    "BumpOptions",
    "HonestRule",
    "Laser",
    "LaserRun",
    "ScanCounts",
    "SimulatedMap",
    "SimulatedPartition",
    "apply_bumps",
    "broken_plan_map",
    "cast_rays",
    "counts_to_map",
    "draw_bumps",
    "draw_k_bumps",
    "frame_truth",
    "generate_building",
    "grid_geometry",
    "map_in_frame",
    "map_prefixes",
    "map_scans",
    "plan_map",
    "plan_route",
    "route_poses",
    "save_simulation",
    "scan_counts",
    "simulate_broken_map",
    "simulate_plan_run",
    "simulate_run",
]
