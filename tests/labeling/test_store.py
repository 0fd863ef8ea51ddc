"""The labeling tool's data layer on SQLite and on a real PostgreSQL server: schema, routing with locks,
submission, consensus and review, export and its round trip through the dataset."""

from __future__ import annotations

import json
import threading
from datetime import timedelta
from pathlib import Path

import pytest
from alembic.autogenerate import compare_metadata
from alembic.migration import MigrationContext
from builders import SUGGESTED, add_user, labels_body, make_label_dataset
from sqlalchemy import func, select

from langtraj.errors import InputError
from langtraj.interdrive.dataset import iter_records
from langtraj.interdrive.labels import LabelSource
from langtraj.labeling import review, tasks
from langtraj.labeling.db import Database
from langtraj.labeling.errors import Conflict, Forbidden
from langtraj.labeling.export import export_accepted
from langtraj.labeling.models import Annotation, Base, Role, Slot, SlotState, Task
from langtraj.labeling.protocol import parse_labels

AGENTS = {7, 17, 27, 37}


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return make_label_dataset(tmp_path_factory.mktemp("labeling"))


@pytest.fixture(params=["sqlite", "postgresql"])
def db(request: pytest.FixtureRequest, tmp_path: Path) -> Database:
    url = (
        f"sqlite:///{tmp_path / 'labels.sqlite'}"
        if request.param == "sqlite"
        else request.getfixturevalue("postgres_url")
    )
    database = Database(url)
    yield database
    database.dispose()


def labels(a: str = "passing/intersection_with_yielding", b: str = SUGGESTED, text: str = ""):
    body = labels_body(a, b, text)
    return parse_labels(body["pair"], body["choices"])


def test_migrations_create_exactly_the_models_schema(db: Database) -> None:
    with db.engine.connect() as connection:
        assert compare_metadata(MigrationContext.configure(connection), Base.metadata) == []


def test_tasks_come_from_the_dataset_with_pair_and_suggestions(db: Database, dataset: Path) -> None:
    assert tasks.add_tasks(db, dataset, overlap=2) == (3, 0)
    assert tasks.add_tasks(db, dataset, overlap=2) == (0, 3)
    view = tasks.task_view(db, 1)
    assert view["pair"] == [7, 17] and view["pair_source"] == "objects_of_interest"
    assert {a["id"] for a in view["agents"]} == AGENTS
    assert {"track_id": 17, "other_id": 7, "subtype": SUGGESTED} in view["suggestions"]
    with db.session() as session:
        assert session.scalar(select(func.count()).select_from(Slot)) == 6


def test_unknown_window_or_bad_overlap_writes_nothing(db: Database, dataset: Path) -> None:
    with pytest.raises(InputError, match="no window 'nope'"):
        tasks.add_tasks(db, dataset, ["win-0", "nope"])
    with pytest.raises(InputError, match="--quorum"):
        tasks.add_tasks(db, dataset, overlap=2, quorum=3)
    with db.session() as session:
        assert session.scalar(select(func.count()).select_from(Task)) == 0


def test_routing_gives_each_annotator_one_slot_per_window(db: Database, dataset: Path) -> None:
    tasks.add_tasks(db, dataset, ["win-0", "win-1"], overlap=2)
    ann = [add_user(db, f"ann{n}") for n in range(3)]
    first = tasks.claim_next(db, ann[0])
    again = tasks.claim_next(db, ann[0])  # holding one slot, it gets the same one back, its lock renewed
    assert (again.slot_id, again.task_id) == (first.slot_id, first.task_id)
    assert again.locked_until >= first.locked_until
    second = tasks.claim_next(db, ann[1])
    assert (first.task_id, second.task_id) == (1, 1) and first.slot_id != second.slot_id
    third = tasks.claim_next(db, ann[2])
    assert third.task_id == 2  # window 1's two slots are held
    tasks.submit(db, ann[0], first.slot_id, "sub-a0-1", labels(), 1000, {})
    nxt = tasks.claim_next(db, ann[0])
    assert nxt.task_id == 2 and nxt.slot_id != third.slot_id  # never window 1 again
    tasks.submit(db, ann[0], nxt.slot_id, "sub-a0-2", labels(), 1000, {})
    assert tasks.claim_next(db, ann[0]) is None  # nothing left for it


def test_expired_lock_goes_to_another_and_the_first_cannot_submit(db: Database, dataset: Path) -> None:
    tasks.add_tasks(db, dataset, ["win-0"], overlap=1)
    a, b = add_user(db, "a"), add_user(db, "b")
    claim = tasks.claim_next(db, a, lock=timedelta(seconds=-1))  # expired at once
    assert tasks.claim_next(db, b).slot_id == claim.slot_id
    with pytest.raises(Forbidden):
        tasks.submit(db, a, claim.slot_id, "sub-late-a", labels(), 10, {})
    tasks.submit(db, b, claim.slot_id, "sub-b", labels(), 10, {})


def test_release_expired_returns_locks_to_the_queue(db: Database, dataset: Path) -> None:
    tasks.add_tasks(db, dataset, ["win-0", "win-1"], overlap=1)
    a, b = add_user(db, "a"), add_user(db, "b")
    tasks.claim_next(db, b)
    tasks.claim_next(db, a, lock=timedelta(seconds=-1))
    assert tasks.release_expired(db) == 1
    with db.session() as session:
        states = dict(session.execute(select(Slot.task_id, Slot.state)).all())
    assert states == {1: SlotState.LOCKED.value, 2: SlotState.OPEN.value}


def test_concurrent_claims_never_share_a_slot(db: Database, dataset: Path) -> None:
    tasks.add_tasks(db, dataset, overlap=3)
    users = [add_user(db, f"u{n}") for n in range(9)]
    claims: dict[str, object] = {}
    barrier = threading.Barrier(len(users))

    def claim(user) -> None:  # type: ignore[no-untyped-def]
        barrier.wait()
        claims[user.name] = tasks.claim_next(db, user)

    threads = [threading.Thread(target=claim, args=(u,)) for u in users]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    slots = [c.slot_id for c in claims.values()]
    assert len(slots) == 9 and len(set(slots)) == 9
    with db.session() as session:
        held = session.execute(select(Slot.annotator_id).where(Slot.state == SlotState.LOCKED.value)).scalars().all()
    assert sorted(held) == sorted(u.id for u in users)


def test_submit_is_idempotent_and_only_for_the_holder(db: Database, dataset: Path) -> None:
    tasks.add_tasks(db, dataset, ["win-0"], overlap=2)
    a, b = add_user(db, "a"), add_user(db, "b")
    claim = tasks.claim_next(db, a)
    with pytest.raises(Forbidden):
        tasks.submit(db, b, claim.slot_id, "sub-b-steal", labels(), 10, {})
    first = tasks.submit(db, a, claim.slot_id, "sub-a-1", labels(), 10, {"pair": 3})
    assert first[1] is True
    assert tasks.submit(db, a, claim.slot_id, "sub-a-1", labels(), 10, {}) == (first[0], False)
    with pytest.raises(Conflict):
        tasks.submit(db, a, claim.slot_id, "sub-a-2", labels(), 10, {})
    with db.session() as session:
        assert session.scalar(select(func.count()).select_from(Annotation)) == 1


def test_consensus_accepts_and_disagreement_goes_to_review(db: Database, dataset: Path) -> None:
    tasks.add_tasks(db, dataset, ["win-0", "win-1"], overlap=2)
    a, b = add_user(db, "a"), add_user(db, "b")
    rev = add_user(db, "rev", Role.REVIEWER)
    for user, tag in ((a, "a"), (b, "b")):
        tasks.submit(db, user, tasks.claim_next(db, user).slot_id, f"sub-{tag}-1", labels(), 10, {})  # agree
    other = labels(a="other/undefined", text="weaves between both lanes")
    tasks.submit(db, a, tasks.claim_next(db, a).slot_id, "sub-a-2", labels(), 10, {})
    tasks.submit(db, b, tasks.claim_next(db, b).slot_id, "sub-b-2", other, 10, {})
    stats = review.agreement(db)
    assert [w["status"] for w in stats["windows"]][:2] == ["accepted (consensus)", "disagreement"]
    assert [w["agreement"] for w in stats["windows"]][:2] == [1.0, 0.0]
    assert stats["annotators"]["a"]["pairwise"] == 0.5
    queued = review.queue(db)
    assert [q["task_id"] for q in queued] == [2]
    texts = {c["text"] for ann in queued[0]["annotations"] for c in ann["choices"]}
    assert "weaves between both lanes" in texts
    pick = next(x["annotation_id"] for x in queued[0]["annotations"] if x["annotator"] == "b")
    review.accept(db, rev, 2, pick, None)
    assert review.queue(db) == []
    assert review.agreement(db)["annotators"]["b"]["with_accepted"] == 1.0


def test_owner_edits_until_accepted_and_nobody_else_can(db: Database, dataset: Path) -> None:
    tasks.add_tasks(db, dataset, ["win-0"], overlap=2)
    a, b = add_user(db, "a"), add_user(db, "b")
    aid, _ = tasks.submit(db, a, tasks.claim_next(db, a).slot_id, "sub-a-1", labels(), 10, {})
    with pytest.raises(Forbidden):
        tasks.edit(db, b, aid, labels(b="other/unknown"))
    tasks.edit(db, a, aid, labels(b="other/unknown"))
    tasks.submit(db, b, tasks.claim_next(db, b).slot_id, "sub-b-1", labels(b="other/unknown"), 10, {})
    with pytest.raises(Conflict, match="accepted"):
        tasks.edit(db, a, aid, labels())


def test_export_round_trips_into_the_dataset_with_an_audit(db: Database, tmp_path: Path) -> None:
    dataset = make_label_dataset(tmp_path / "own", num_scenes=2)
    tasks.add_tasks(db, dataset, overlap=2)
    a, b = add_user(db, "a"), add_user(db, "b")
    kept = labels(a="yielding/to_pedestrian", b=SUGGESTED)
    changed = labels(a="yielding/to_pedestrian", b="other/undefined", text="<b>walks</b> & <script>x()</script>")
    for n, lab in enumerate((kept, changed)):
        for user in (a, b):
            tasks.submit(
                db, user, tasks.claim_next(db, user).slot_id, f"sub-{user.name}-{n}", lab, 500 + n, {"pair": 1}
            )
    result = export_accepted(db, tmp_path / "out" / "json", tmp_path / "out" / "audit.json", into=dataset)
    assert (result.written, result.pending, result.imported) == (2, 0, 2)
    doc = json.loads((tmp_path / "out" / "json" / "win-1.json").read_text())
    assert doc["agent_1"]["no_behavior_description"] == "<b>walks</b> & <script>x()</script>"
    human = {
        r.scenario_id: {
            (i.track_id, i.other_id, i.subtype.id, i.text)
            for i in r.labels.interactions
            if i.source is LabelSource.HUMAN
        }
        for _, recs in iter_records(dataset)
        for r in recs
    }
    for scenario_id, lab in (("win-0", kept), ("win-1", changed)):
        assert human[scenario_id] == {(c.track_id, c.other_id, c.subtype.id, c.text) for c in lab.choices}
    audit = json.loads((tmp_path / "out" / "audit.json").read_text())
    by_window = {w["scenario_id"]: w for w in audit["windows"]}
    suggestion = {
        w: {c["suggestion"] for ann in by_window[w]["annotations"] for c in ann["choices"] if c["track_id"] == 17}
        for w in by_window
    }
    assert suggestion == {"win-0": {"kept"}, "win-1": {"changed"}}
    first = by_window["win-0"]["annotations"][0]
    assert (
        first["annotator"] == "a"
        and first["lead_time_ms"] == 500
        and by_window["win-0"]["accepted"]["method"] == "consensus"
    )


def test_concurrent_last_submits_still_reach_consensus(db: Database, dataset: Path) -> None:
    """The last two submits of a window racing each other: the task row lock makes the second see the first."""
    tasks.add_tasks(db, dataset, overlap=2)
    users = [add_user(db, f"r{n}") for n in range(6)]
    claims = [(u, tasks.claim_next(db, u)) for u in users]
    barrier = threading.Barrier(len(claims))

    def go(user, claim) -> None:  # type: ignore[no-untyped-def]
        barrier.wait()
        tasks.submit(db, user, claim.slot_id, f"race-{user.name}", labels(), 10, {})

    threads = [threading.Thread(target=go, args=pair) for pair in claims]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    with db.session() as session:
        assert session.scalar(select(func.count()).select_from(Annotation)) == 6
    assert [w["status"] for w in review.agreement(db)["windows"]] == ["accepted (consensus)"] * 3


def test_labels_naming_an_agent_outside_the_window_are_refused_and_write_nothing(db: Database, dataset: Path) -> None:
    tasks.add_tasks(db, dataset, ["win-0"], overlap=2)
    a, rev = add_user(db, "a"), add_user(db, "rev", Role.REVIEWER)
    body = {**labels_body(), "pair": [7, 99]}
    body["choices"][1] = {**body["choices"][1], "track_id": 99}
    body["choices"][0] = {**body["choices"][0], "other_id": 99}
    stranger = parse_labels(body["pair"], body["choices"])
    claim = tasks.claim_next(db, a)
    with pytest.raises(InputError, match="agent 99 is not in this window"):
        tasks.submit(db, a, claim.slot_id, "sub-stranger", stranger, 10, {})
    with db.session() as session:
        assert session.scalar(select(func.count()).select_from(Annotation)) == 0
        assert session.get(Slot, claim.slot_id).state == SlotState.LOCKED.value  # still held
    aid, _ = tasks.submit(db, a, claim.slot_id, "sub-a", labels(), 10, {})
    with pytest.raises(InputError, match="agent 99"):
        tasks.edit(db, a, aid, stranger)
    with pytest.raises(InputError, match="agent 99"):
        review.accept(db, rev, 1, None, stranger)
    assert review.agreement(db)["windows"][0]["status"] == "in progress"
