"""The workflows that run a registered solver on a core problem: a raw recording to positions with the
variance detector's threshold search (:mod:`.recording`), discovery's search (:mod:`.discovery`), the
gyroscope's fit (:mod:`.gyro`) and the planner's design search (:mod:`.plan`). This file imports nothing.
"""
