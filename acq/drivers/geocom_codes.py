"""GeoCOM return codes (GRC_*): number -> name, severity and an operator text.

Sources: protocols.md §1.8 (GeoComPy gctypes.py and DMPACK dm_geocom_error.f90 agree).  Severity decides what the
driver does: ``ok`` -> values; ``warning``/``info`` -> values are usable and the code travels with the reading;
``error`` -> :class:`~acq.errors.InstrumentError`.  Codes missing from the table still get a clear text from their
subsystem range (:func:`describe`), so *every* code maps to an error or a warning.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class ReturnCode:
    code: int
    name: str
    severity: str          # "ok" | "warning" | "info" | "error"
    text: str

    @property
    def usable(self) -> bool:
        """True when the reply's values may be used (RC 0 and the TMC warning/info codes that carry values)."""
        return self.severity != "error"


_E, _W, _I = "error", "warning", "info"

_TABLE: list[tuple[int, str, str, str]] = [
    (0, "OK", "ok", "function successfully completed"),
    (1, "UNDEFINED", _E, "unknown error, result unspecified"),
    (2, "IVPARAM", _E, "invalid parameter detected; result unspecified"),
    (3, "IVRESULT", _E, "invalid result"),
    (4, "FATAL", _E, "fatal error"),
    (5, "NOT_IMPL", _E, "not implemented on this instrument"),
    (6, "TIME_OUT", _E, "function execution timed out on the instrument"),
    (7, "SET_INCOMPL", _E, "parameter setup incomplete"),
    (8, "ABORT", _E, "function execution aborted"),
    (9, "NOMEMORY", _E, "instrument out of memory"),
    (10, "NOTINIT", _E, "subsystem not initialised"),
    (12, "SHUT_DOWN", _E, "subsystem is down"),
    (13, "SYSBUSY", _E, "system busy; repeat later"),
    (14, "HWFAILURE", _E, "hardware failure"),
    (15, "ABORT_APPL", _E, "application aborted"),
    (16, "LOW_POWER", _E, "battery low"),
    (17, "IVVERSION", _E, "invalid version of file"),
    (18, "BATT_EMPTY", _E, "battery empty"),
    (20, "NO_EVENT", _E, "no event pending"),
    (21, "OUT_OF_TEMP", _E, "instrument out of its temperature range"),
    (22, "INSTRUMENT_TILT", _E, "instrument tilted out of the compensator range: relevel it"),
    (23, "COM_SETTING", _E, "communication settings error"),
    (24, "NO_ACTION", _E, "no action taken"),
    (25, "SLEEP_MODE", _E, "instrument in sleep mode"),
    (26, "NOTOK", _E, "function not successfully completed"),
    (27, "NA", _E, "not available (licence key missing)"),
    (28, "OVERFLOW", _E, "overflow error"),
    (29, "STOPPED", _E, "system or subsystem stopped"),
    # ANG
    (257, "ANG_ERROR", _E, "angles and inclinations not valid"),
    (258, "ANG_INCL_ERROR", _E, "inclinations not valid"),
    (259, "ANG_BAD_ACC", _E, "angle accuracy insufficient"),
    (260, "ANG_BAD_ANGLE_ACC", _E, "angle accuracy insufficient"),
    (261, "ANG_BAD_INCLIN_ACC", _E, "inclination accuracy insufficient"),
    # TMC
    (1283, "TMC_NO_FULL_CORRECTION", _W, "measurement without full correction"),
    (1284, "TMC_ACCURACY_GUARANTEE", _I, "accuracy cannot be guaranteed"),
    (1285, "TMC_ANGLE_OK", _W, "only the angle measurement is valid (no distance)"),
    (1288, "TMC_ANGLE_NOT_FULL_CORR", _W, "only angles valid, without full correction"),
    (1289, "TMC_ANGLE_NO_ACC_GUARANTY", _I, "only angles valid, accuracy not guaranteed"),
    (1290, "TMC_ANGLE_ERROR", _E, "no angle measurement (angle error)"),
    (1291, "TMC_DIST_PPM", _E, "wrong PPM/MM setting on the EDM"),
    (1292, "TMC_DIST_ERROR", _E, "distance not measured (no target?)"),
    (1293, "TMC_BUSY", _E, "measurement system busy; repeat"),
    (1294, "TMC_SIGNAL_ERROR", _E, "no EDM signal"),
    (1380, "TMC_OLD_PLANE", _W, "inclination plane model is old"),
    (1381, "TMC_NO_PLANE", _E, "no inclination plane model"),
    (1383, "TMC_INCLINE_ACC", _E, "inclination accuracy insufficient"),
    (1392, "TMC_INC_ERROR", _E, "inclination sensor error"),
    # MOT
    (1792, "MOT_UNREADY", _E, "motorisation not ready"),
    (1793, "MOT_BUSY", _E, "motorisation busy"),
    (1794, "MOT_NOT_OCONST", _E, "motorisation not in velocity mode"),
    (1795, "MOT_NOT_CONFIG", _E, "motorisation in the wrong mode or busy"),
    (1796, "MOT_NOT_POSIT", _E, "motorisation not in positioning mode"),
    (1797, "MOT_NOT_SERVICE", _E, "motorisation not in service mode"),
    (1798, "MOT_NOT_BUSY", _E, "motorisation not busy"),
    (1799, "MOT_NOT_LOCK", _E, "motorisation not in tracking mode"),
    (1800, "MOT_NOT_SPIRAL", _E, "motorisation not in spiral mode"),
    (1801, "MOT_V_ENCODER", _E, "vertical encoder/motor error"),
    (1802, "MOT_HZ_ENCODER", _E, "horizontal encoder/motor error"),
    (1803, "MOT_HZ_V_ENCODER", _E, "horizontal and vertical encoder/motor error"),
    # COM
    (3072, "COM_ERO", _E, "initiate extended runtime operation"),
    (3073, "COM_CANT_ENCODE", _E, "cannot encode arguments in client"),
    (3074, "COM_CANT_DECODE", _E, "cannot decode results in client"),
    (3075, "COM_CANT_SEND", _E, "hardware error while sending"),
    (3076, "COM_CANT_RECV", _E, "hardware error while receiving"),
    (3077, "COM_TIMEDOUT", _E, "request timed out"),
    (3078, "COM_WRONG_FORMAT", _E, "packet format error"),
    (3079, "COM_VER_MISMATCH", _E, "version mismatch between client and server"),
    (3080, "COM_CANT_DECODE_REQ", _E, "instrument cannot decode the request"),
    (3081, "COM_PROC_UNAVAIL", _E, "unknown RPC, procedure unavailable on this instrument"),
    (3082, "COM_CANT_ENCODE_REP", _E, "instrument cannot encode the reply"),
    (3083, "COM_SYSTEM_ERR", _E, "communication hardware error"),
    (3085, "COM_FAILED", _E, "unknown communication error"),
    (3086, "COM_NO_BINARY", _E, "binary protocol not available"),
    (3087, "COM_INTR", _E, "call interrupted"),
    (3090, "COM_REQUIRES_8DBITS", _E, "protocol needs 8 data bits"),
    (3093, "COM_TR_ID_MISMATCH", _E, "reply transaction id does not match the request"),
    (3094, "COM_NOT_GEOCOM", _E, "reply is not a GeoCOM frame"),
    (3095, "COM_UNKNOWN_PORT", _E, "unknown port"),
    (3099, "COM_ERO_END", _E, "end of extended runtime operation"),
    (3100, "COM_OVERRUN", _E, "buffer overrun"),
    (3101, "COM_SRVR_RX_CHECKSUM_ERROR", _E, "instrument received a request with a bad checksum"),
    (3102, "COM_CLNT_RX_CHECKSUM_ERROR", _E, "reply with a bad checksum"),
    (3103, "COM_PORT_NOT_AVAILABLE", _E, "port not available"),
    (3104, "COM_PORT_NOT_OPEN", _E, "port not open"),
    (3105, "COM_NO_PARTNER", _E, "no partner on the other side"),
    (3106, "COM_ERO_NOT_STARTED", _E, "extended runtime operation could not be started"),
    (3107, "COM_CONS_REQ", _E, "attention to send consecutive requests"),
    (3108, "COM_SRVR_IS_SLEEPING", _E, "instrument is sleeping; wake it up"),
    (3109, "COM_SRVR_IS_OFF", _E, "instrument is switched off"),
    (3110, "COM_NO_CHECKSUM", _E, "no checksum in ASCII protocol available"),
    # AUT
    (8704, "AUT_TIMEOUT", _E, "positioning not completed in time"),
    (8705, "AUT_DETENT_ERROR", _E, "positioning failed: detent error"),
    (8706, "AUT_ANGLE_ERROR", _E, "positioning failed: angle error"),
    (8707, "AUT_MOTOR_ERROR", _E, "motorisation error"),
    (8708, "AUT_INCACC", _E, "position not exactly reached"),
    (8709, "AUT_DEV_ERROR", _E, "deviation measurement error"),
    (8710, "AUT_NO_TARGET", _E, "no target detected"),
    (8711, "AUT_MULTIPLE_TARGETS", _E, "multiple targets detected"),
    (8712, "AUT_BAD_ENVIRONMENT", _E, "bad environment conditions"),
    (8713, "AUT_DETECTOR_ERROR", _E, "error in target acquisition"),
    (8714, "AUT_NOT_ENABLED", _E, "target acquisition not enabled"),
    (8715, "AUT_CALACC", _E, "ATR calibration failed"),
    (8716, "AUT_ACCURACY", _E, "target position not exactly reached"),
    (8717, "AUT_DIST_STARTED", _E, "distance measurement started"),
    (8718, "AUT_SUPPLY_TOO_HIGH", _E, "external supply voltage too high"),
    (8719, "AUT_SUPPLY_TOO_LOW", _E, "internal or external supply voltage too low"),
    (8720, "AUT_NO_WORKING_AREA", _E, "working area not set"),
    (8721, "AUT_ARRAY_FULL", _E, "power search data array full"),
    (8722, "AUT_NO_DATA", _E, "no data available"),
    (9217, "BAP_CHANGE_ALL_TO_DIST", _W, "no prism found; measured reflectorless"),
]

#: TMC/BAP codes whose reply carries angles but *no valid distance* (protocols.md §1.8): a distance sent with them
#: is a placeholder and must never become a reading
ANGLES_ONLY = frozenset({1285, 1288, 1289})

RETURN_CODES: dict[int, ReturnCode] = {c: ReturnCode(c, n, s, t) for c, n, s, t in _TABLE}

#: subsystem ranges for codes not in the table (EDM numbering differs between sources: log the number)
_RANGES: list[tuple[int, int, str]] = [
    (256, 326, "ANG (angle sensor)"), (513, 600, "ATA"), (769, 826, "EDM"), (1024, 1100, "GMF"),
    (1283, 1400, "TMC (measurement)"), (1536, 1600, "MEM"), (1792, 1810, "MOT (motorisation)"),
    (2048, 2100, "LDR"), (2304, 2400, "BMM"), (3072, 3110, "COM (communication)"), (8704, 8725, "AUT (automation)"),
    (9216, 9300, "BAP"), (12544, 12600, "KDM"),
]


def describe(code: int) -> ReturnCode:
    """The ReturnCode for any number; unknown codes are errors named after their subsystem range."""
    rc = RETURN_CODES.get(code)
    if rc is not None:
        return rc
    for lo, hi, group in _RANGES:
        if lo <= code <= hi:
            return ReturnCode(code, f"{group.split()[0]}_{code}", _E, f"{group} error {code}")
    return ReturnCode(code, f"GRC_{code}", _E, f"unknown return code {code}")
