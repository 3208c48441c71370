"""The social task in the physics arena (issue 18): a kinematic human beside the TurtleBot.

* :mod:`simlab.social.human` — the projected human (pose, presets, random walk, following);
* :mod:`simlab.social.perception` — fields, line of sight, distance classes, social index;
* :mod:`simlab.social.actions` — LOOK_H, signals, GO_TO_HUMAN on the robot;
* :mod:`simlab.social.task` — :class:`~simlab.social.task.SocialTable` (reset / step).
"""
