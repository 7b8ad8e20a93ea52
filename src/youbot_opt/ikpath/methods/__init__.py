"""The two methods of the cyclic IK path: augmented Lagrangian (``al``) and IPOPT.

:mod:`.al` is the study's augmented Lagrangian with the projected BFGS of
:mod:`.bfgs`; :mod:`.ipopt` solves the same NLP in CasADi with IPOPT; both keep
the best iterate they visited (:mod:`.best_iterate`).

    from youbot_opt.ikpath.methods.al import ALOptions
"""
