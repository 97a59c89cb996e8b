"""Scan matching: each particle's scan against its own map (see matcher.py)."""
from fastslam.match.matcher import Match, MatchParams, match_poses, refine_poses

__all__ = ["Match", "MatchParams", "match_poses", "refine_poses"]
