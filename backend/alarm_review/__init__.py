"""Alarm review for nurses: replay, history, alarm-fatigue statistics and verdict feedback."""
