"""A search mission on the team's own ground (``attend plan``): the area from GeoJSON, KML or a
QGroundControl .plan, the images and detections flown so far, the probability map rebuilt from
them, the next plan for every UAV and the likely people.

Data path: mission file (:func:`read_mission`) -> :class:`SearchGround` (local frame, grid,
routes inside the area) -> :class:`Mission` (map from the logs, targets, plans) ->
:func:`write_outputs` (plan.csv, .plan, .waypoints, .geojson, targets.csv, map.png, map.tif,
summary.json); :func:`simulate_mission` flies a whole mission with the built-in simulator.
"""

from attend.action.mission.config import MissionConfig, UavConfig, read_mission
from attend.action.mission.errors import MissionInputError
from attend.action.mission.ground import LocalFrame, SearchGround
from attend.action.mission.mission import Mission, UavPlan
from attend.action.mission.outputs import write_outputs

__all__ = ["LocalFrame", "Mission", "MissionConfig", "MissionInputError", "SearchGround", "UavConfig", "UavPlan",
           "read_mission", "write_outputs"]
