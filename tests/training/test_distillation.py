"""Distillation from K = 100 to K = 5 steps by training on the 5-step schedule from the K = 100 weights
(docs/model.md, 'Distillation'): the 5-step schedule has the noise levels that the K = 100 model's
5-step DDIM sampler visits, and the step embedding names them alike, so the student starts where the
teacher samples."""

from __future__ import annotations

import torch
from scenario_builders import make_scenario

from langtraj.model import LangTraj, ModelConfig
from langtraj.model.config import SampleConfig
from langtraj.model.diffusion import cosine_schedule, timestep_sequence
from langtraj.model.features import collate_scenes, scene_sample
from langtraj.model.layers import step_embedding

CONFIG = ModelConfig(hidden_dim=32, num_heads=4, encoder_layers=1, denoiser_blocks=1, dropout=0.0, use_text=False)


def test_the_five_step_schedule_has_the_noise_levels_the_teachers_five_ddim_steps_visit():
    teacher, student = cosine_schedule(100), cosine_schedule(5)
    visited = timestep_sequence(100, num_inference_steps=5)
    assert visited == [99, 79, 59, 39, 19]
    # all but the top level, where both schedules clip beta at 0.999 (pure noise either way)
    torch.testing.assert_close(student.alphas_cumprod[:4], teacher.alphas_cumprod[[19, 39, 59, 79]])
    assert student.alphas_cumprod[4] < 0.002 and teacher.alphas_cumprod[99] < 0.002


def test_the_student_embeds_its_steps_as_the_teacher_embeds_the_same_noise_levels():
    torch.manual_seed(0)
    teacher = LangTraj(CONFIG)
    student = LangTraj(ModelConfig(**{**CONFIG.to_dict(), "text": CONFIG.text, "diffusion_steps": 5}))
    student.load_state_dict(teacher.state_dict())
    for k_student, k_teacher in zip(range(5), (19, 39, 59, 79, 99), strict=True):
        k_s, k_t = torch.tensor([k_student]), torch.tensor([k_teacher])
        embed_s = step_embedding((k_s.float() + 1) * student.denoiser.step_scale - 1, 32)
        torch.testing.assert_close(embed_s, step_embedding(k_t, 32))
    data = SampleConfig(max_agents=6, max_polylines=12, points_per_polyline=10, text=False)
    batch = collate_scenes([scene_sample(make_scenario(5), data)])
    teacher_states, _ = teacher.eval().sample(batch, 2, steps=5, generator=torch.Generator().manual_seed(3))
    student_states, _ = student.eval().sample(batch, 2, steps=5, generator=torch.Generator().manual_seed(3))
    # identical but for the top noise level (clipped differently): the student starts at the teacher
    gap = (teacher_states[..., :2] - student_states[..., :2]).abs().max()
    assert float(gap) < 0.05 * float(teacher_states[..., :2].abs().max()) + 0.05
