"""Verdicts by published rules: ISO 15622's ACC envelope (:mod:`acc_gym.standards.iso15622`) and
the batteries that exercise it (:mod:`acc_gym.standards.battery`)."""
