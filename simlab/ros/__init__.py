"""ROS 2 bags (MCAP) in and out, with the pure-Python ``rosbags`` library (``ros`` extra).

:mod:`simlab.ros.bag` writes and reads the bag (:class:`~simlab.ros.bag.BagTrajectory`),
:mod:`simlab.ros.export` turns a collection or a replay into one (``simlab export-bag``),
:mod:`simlab.ros.importer` turns a robot's bag into a simlab dataset (``simlab import-bag``),
:mod:`simlab.ros.markers` holds the geometry of the cells and goals a bag shows.
No ROS installation is needed.
"""
