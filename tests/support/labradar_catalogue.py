"""The real LabRadar series in ``../shared/data/labradar`` (one shooter's device, 2020-2022) that a
session can be judged on, with each bullet as the owner's notes name it.

Included: every series whose notes name one bullet (mass from the notes; diameter the
calibre's nominal bullet diameter). Left out, with the reason: SR0005 and SR0011 of 2020-2021
(121 and 124 gr bullets mixed), SR0032 (an unknown black-powder bullet), SR0037 ("JUNK
SESSION"), 2022/SR0007 (no note), 2022/Maverick-308 (reports only, no tracks). The reference
shape is G7 for boat-tailed spitzers and G1 for flat-based, round-nosed and pistol bullets; the
session's correction polynomial takes up what the data determine beyond it.

Kinds: ``rifle`` (centrefire rifle: the 1.5 % gate applies with 8+ shots), ``rimfire`` (.22 LR,
crossing the sound barrier), ``pistol``.
"""
from __future__ import annotations

GRAIN = 6.479891e-5     # kg
INCH = 0.0254           # m

#: calibre -> nominal bullet diameter [m]
DIAMETER = {"8mm": 0.323 * INCH, "6.5": 0.264 * INCH, ".223": 0.224 * INCH, ".284": 0.284 * INCH,
            ".22lr": 0.2255 * INCH, "9mm": 0.355 * INCH, ".45": 0.452 * INCH}

#: (folder below data/labradar, calibre, bullet mass [gr], reference, kind, bullet)
SERIES = [
    ("2020-2021/SR0001", "8mm", 180, "G7", "rifle", "Barnes TSX"),
    ("2020-2021/SR0002", ".45", 230, "G1", "pistol", "CamPro RN"),
    ("2020-2021/SR0003", ".45", 230, "G1", "pistol", "CamPro RN"),
    ("2020-2021/SR0004", ".45", 230, "G1", "pistol", "CamPro RN"),
    ("2020-2021/SR0006", ".22lr", 36, "G1", "rimfire", "Sterling Cross"),
    ("2020-2021/SR0007", ".22lr", 36, "G1", "rimfire", "Federal Black Pack"),
    ("2020-2021/SR0008", ".22lr", 38, "G1", "rimfire", "Aguila Super Extra HP"),
    ("2020-2021/SR0009", ".45", 230, "G1", "pistol", "Federal factory"),
    ("2020-2021/SR0010", ".45", 230, "G1", "pistol", "CamPro RN"),
    ("2020-2021/SR0012", ".22lr", 36, "G1", "rimfire", "Sterling Cross"),
    ("2020-2021/SR0013", ".22lr", 36, "G1", "rimfire", "Federal Black Pack"),
    ("2020-2021/SR0014", ".22lr", 38, "G1", "rimfire", "Aguila Super Extra HP"),
    ("2020-2021/SR0015", ".45", 230, "G1", "pistol", "CamPro RN"),
    ("2020-2021/SR0016", "6.5", 140, "G7", "rifle", "Sierra MatchKing"),
    ("2020-2021/SR0017", "6.5", 140, "G7", "rifle", "Hornady HPBT"),
    ("2020-2021/SR0018", "6.5", 107, "G7", "rifle", "Sierra MatchKing"),
    ("2020-2021/SR0019", "8mm", 170, "G1", "rifle", "Federal"),
    ("2020-2021/SR0020", "8mm", 170, "G1", "rifle", "CIL"),
    ("2020-2021/SR0021", "8mm", 170, "G1", "rifle", "Hornady RN"),
    ("2020-2021/SR0022", "8mm", 180, "G7", "rifle", "Nosler Ballistic Tip"),
    ("2020-2021/SR0023", "8mm", 180, "G7", "rifle", "Barnes TSX"),
    ("2020-2021/SR0024", "6.5", 130, "G7", "rifle", "Hornady ELD-X"),
    ("2020-2021/SR0025", ".223", 55, "G1", "rifle", "Norinco FMJ"),
    ("2020-2021/SR0026", ".223", 55, "G1", "rifle", "Lake City FMJ"),
    ("2020-2021/SR0027", "6.5", 140, "G1", "rifle", "Hornady Interlock"),
    ("2020-2021/SR0028", "6.5", 140, "G7", "rifle", "Hornady HPBT"),
    ("2020-2021/SR0029", "6.5", 140, "G7", "rifle", "Hornady SST"),
    ("2020-2021/SR0030", ".223", 69, "G7", "rifle", "Sierra MatchKing"),
    ("2020-2021/SR0031", ".223", 55, "G1", "rifle", "Lake City FMJ"),
    ("2020-2021/SR0033", ".22lr", 36, "G1", "rimfire", "Federal Black Pack"),
    ("2020-2021/SR0034", "8mm", 170, "G1", "rifle", "CIL Spitzer"),
    ("2020-2021/SR0035", "8mm", 180, "G7", "rifle", "Barnes TSX"),
    ("2020-2021/SR0036", ".22lr", 36, "G1", "rimfire", "Federal Black Pack"),
    ("2020-2021/SR0038", ".22lr", 36, "G1", "rimfire", "Federal Black Pack"),
    ("2020-2021/SR0039", ".22lr", 40, "G1", "rimfire", "CCI SV"),
    ("2020-2021/SR0040", ".22lr", 40, "G1", "rimfire", "Eley Force"),
    ("2020-2021/SR0041", ".22lr", 36, "G1", "rimfire", "Federal Black Pack"),
    ("2020-2021/SR0042", ".22lr", 40, "G1", "rimfire", "CCI SV"),
    ("2020-2021/SR0043", "8mm", 150, "G1", "rifle", "Hornady SP"),
    ("2020-2021/SR0044", "8mm", 180, "G7", "rifle", "Barnes TSX"),
    ("2020-2021/SR0045", "6.5", 140, "G7", "rifle", "Hornady"),
    ("2020-2021/SR0046", "6.5", 140, "G7", "rifle", "Hornady"),
    ("2020-2021/SR0047", "6.5", 142, "G7", "rifle", "Sierra MatchKing"),
    ("2020-2021/SR0048", "6.5", 142, "G7", "rifle", "Sierra MatchKing"),
    ("2020-2021/SR0049", "6.5", 142, "G7", "rifle", "Sierra MatchKing"),
    ("2020-2021/SR0050", "6.5", 142, "G7", "rifle", "Sierra MatchKing"),
    ("2020-2021/SR0051", "6.5", 142, "G7", "rifle", "Sierra MatchKing"),
    ("2020-2021/SR0052", "6.5", 142, "G7", "rifle", "Sierra MatchKing"),
    ("2020-2021/SR0053", "6.5", 85, "G7", "rifle", "Sierra MatchKing"),
    ("2020-2021/SR0054", "6.5", 85, "G7", "rifle", "Sierra MatchKing"),
    ("2022/LBR0013797201909141617/SR0001", "6.5", 142, "G7", "rifle", "Sierra MatchKing"),
    ("2022/LBR0013797201909141617/SR0002", "6.5", 123, "G7", "rifle", "Hornady SST"),
    ("2022/LBR0013797201909141617/SR0003", "6.5", 123, "G7", "rifle", "Hornady SST"),
    ("2022/LBR0013797201909141617/SR0004", "6.5", 123, "G7", "rifle", "Hornady SST"),
    ("2022/LBR0013797201909141617/SR0005", "6.5", 123, "G7", "rifle", "Hornady SST"),
    ("2022/LBR0013797201909141617/SR0006", "6.5", 123, "G7", "rifle", "Hornady Black"),
    ("2022/LBR0013797201909141617/SR0008", ".284", 168, "G7", "rifle", "Hornady Moly"),
    ("2022/LBR0013797201909141617/SR0009", ".284", 168, "G7", "rifle", "Hornady Moly"),
    ("2022/LBR0013797201909141617/SR0010", ".284", 168, "G7", "rifle", "Hornady Moly"),
    ("2022/LBR0013797201909141617/SR0011", ".284", 168, "G7", "rifle", "Hornady Moly"),
    ("2022/LBR0013797201909141617/SR0012", "6.5", 142, "G7", "rifle", "Sierra MatchKing"),
]

#: series of one bullet fired the same day from the same rifle: their Cd must agree
SAME_DAY = [("2020-2021/SR0047", "2020-2021/SR0048", "2020-2021/SR0049"),
            ("2020-2021/SR0050", "2020-2021/SR0051", "2020-2021/SR0052")]


def round_text(calibre, grains, reference, name=""):
    """A round file for a series: the bullet, ICAO air, the device's offset unknown."""
    return (f'[projectile]\nname = "{name}"\nmass = {grains * GRAIN:.8g}\ndiameter = {DIAMETER[calibre]:.6g}\n'
            f'reference_drag = "{reference}"\n[launch]\nelevation = 0.0\n[atmosphere]\nmodel = "icao"\n')
