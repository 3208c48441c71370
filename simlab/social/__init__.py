"""The social task in the physics arena: a kinematic human beside the TurtleBot.

The thesis's next stage (Future directions): the TurtleBot in a social task with a human
drawn on the table's interactive screen; the social module is thesis 2.1.2's.

* :mod:`simlab.social.human` — the projected human (pose, presets, random walk, following);
* :mod:`simlab.social.perception` — fields, line of sight, distance classes, social index;
* :mod:`simlab.social.actions` — LOOK_H, signals, GO_TO_HUMAN on the robot;
* :mod:`simlab.social.task` — :class:`~simlab.social.task.SocialTable` (reset / step).
"""
