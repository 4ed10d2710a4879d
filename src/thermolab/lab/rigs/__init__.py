"""The lab's rigs as devices: power, safe state, inputs, readings, settings, the image.

* :mod:`.devices` — :class:`~.devices.DeviceHub`: makes each rig match the
  committed access state (the only module that drives a rig's inputs);
* :mod:`.opener` — how a configured rig's driver is opened (a twin on a clock
  whose rate the hub sets, hardware in real time);
* :mod:`.rig_settings` — teachers' settings per rig, within the technician's caps;
* :mod:`.camera` — the live image of a rig.

The drivers themselves are :mod:`thermolab.rigs` (the layer below); rigs on a
remote host are :mod:`thermolab.lab.agents`.
"""
