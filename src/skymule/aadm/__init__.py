"""The AERPAW Autonomous Data Mule (AADM) challenge: its score, files, controller and agent.

* :mod:`~skymule.aadm.score`: the score in force, vectorised over missions;
* :mod:`~skymule.aadm.files`: volume files, the controller's download log, agent<->comm files;
* :mod:`~skymule.io.qgc_plan`: QGroundControl ``.plan`` files (path + geofence);
* :mod:`~skymule.aadm.controller`: a TCP emulator of the challenge controller;
* :mod:`~skymule.aadm.vehicle` / :mod:`~skymule.aadm.agent`: any skymule policy as the UAV agent.
"""
