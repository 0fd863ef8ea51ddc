"""LangTraj Studio: a local web app that turns typed prompts into watched, judged and kept scenarios. Pick a
scene, write prompts, see how each is read and where it steers, simulate in the background, replay the
rollouts, see whether each prompt was followed, and keep the case in a test suite (docs/studio.md)."""
