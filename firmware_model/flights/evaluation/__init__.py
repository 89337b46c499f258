"""The evaluation of the firmware programs on real and simulated flights (`evaluate`, the evaluation set
`evalset`, the parameter `sweep`)."""
