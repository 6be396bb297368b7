"""The papers' physical systems, outside the generic engine: plant simulators, their controllers
and their log formats. Recipes and the CLI use them; ``pfbench.filters``, ``backends``, ``models``,
``resampling`` and ``metrics`` never import them.

* :mod:`.chamber`: the heating/cooling chamber of [Embedded] §3 (plant + DS18B20 sensor);
* :mod:`.datalog`: CSV logs of that chamber (``pfbench run --data``);
* :mod:`.rtd`: the resistance temperature detector of [RTD] (models, RC fit, boundary layer);
* :mod:`.pmsm_control`: PI / cautious / certainty-equivalence control and the closed loop of the
  PMSM drive of [Thesis] ch. 4.
"""
