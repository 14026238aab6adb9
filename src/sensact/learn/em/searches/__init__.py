"""Searches (beyond the thesis): where EM's alternating steps crawl along a ridge of near-equal likelihood,
a direct search by the likelihood itself moves the model along it.

* ``start_race``: where the robot starts when nobody says: a grid of starts scored on the first
  sightings, then a race of short EM runs;
* ``given_start``: a start the user gave, for a sensor without bearings, and whether EM moved it;
* ``ridge``: the path's trade-off with the range functions' offset;
* ``delay``: the command delay;
* ``mount_search``: the sensor's mount (its M-step update is ``learn/em/mount.py``);
* ``facing``: which way is forward, for a robot whose sensor reads no bearing.
"""
