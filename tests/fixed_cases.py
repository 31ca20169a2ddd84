"""Fixed cases the closed-loop tests of every planner share: one easy case per parking type."""

EASY_CASES = (
    "parallel_rw4.00_sl7.32_sw2.50_th+10_y1.30",
    "reverse_rw7.00_sl4.82_sw2.32_th+40_y3.00",
    "angle_rw3.50_sl4.82_sw2.77_th+10_y1.30",
)
