"""Readers for the formats users already have; each converts a recording into a :class:`Session`.

================= ============================================= =========================
format name       what                                          reader
================= ============================================= =========================
``android``       per-sensor ``TIMESTAMP X Y Z`` text files     :func:`read_android`
``sensorlogger``  Sensor Logger (iOS/Android) CSV folder or zip :func:`read_sensorlogger`
``phyphox``       phyphox CSV export (folder, zip or CSV)       :func:`read_phyphox`
``ipin``          IPIN/EvAAL logfile (+ beacon CSV)             :func:`read_ipin`
``hrtls-session`` the session folder/zip                        ``hrtls.io.session``
================= ============================================= =========================

One entry point over these and the public datasets (format detection, ``read_any``) is
:mod:`hrtls.recordings`.
"""

from hrtls.io.readers.android import read_android
from hrtls.io.readers.ipin import ipin_beacon_id, read_beacons_csv, read_ipin
from hrtls.io.readers.phyphox import read_phyphox
from hrtls.io.readers.sensorlogger import read_sensorlogger

__all__ = [
    "ipin_beacon_id",
    "read_android",
    "read_beacons_csv",
    "read_ipin",
    "read_phyphox",
    "read_sensorlogger",
]
