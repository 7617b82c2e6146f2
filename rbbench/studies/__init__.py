"""Reproductions of seed figures (Hertz and Nitsche e_AC tables, online scaling, the beta_dec
stability study): built on the core, never imported by it."""
