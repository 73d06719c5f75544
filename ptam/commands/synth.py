"""``ptam synth SCENE OUT``: render a synthetic sequence (or copy it from the cache); ``--list`` the bundled ones."""

from __future__ import annotations

from ..errors import InputError
from ..synthetic import ensure_sequence, list_scenes
from ..synthetic.board_sequence import CALIBRATION_SCENE, is_calibration_scene, synth_calibration
from ..synthetic.contact_sheet import contact_sheet
from ..synthetic.sequence import copy_sequence


def main(args, cfg) -> int:
    if args.list:
        print("\n".join(list_scenes() + [CALIBRATION_SCENE]))
        return 0
    if not args.scene or not args.out:
        raise InputError("ptam synth: give a SCENE (file or bundled name) and an OUT directory, or --list")
    if is_calibration_scene(args.scene):
        print(synth_calibration(args.scene, args.out, cfg, video=args.video))
        return 0
    src = ensure_sequence(args.scene, cfg.synthetic, video=args.video)
    out = copy_sequence(src, args.out, video=args.video)
    print(f"wrote {out} (cached in {src})")
    if args.contact_sheet:
        print(f"wrote {contact_sheet(out, args.contact_sheet)}")
    return 0
