"""Reduced basis: POD, cones, PGA, inf-sup constants, EIM and the contact hyper-reducers, the
offline skeleton (:mod:`rbbench.rb.offline`), the reduced models (small dense arrays,
picklable) and the shared validation step.
"""
