"""The methods an evaluation compares: each turns a clean image of a real pair into a synthetic noisy one."""
