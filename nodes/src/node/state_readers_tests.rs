//! The shared state readers without DDS: the nodes on one topic share one reader, a node that
//! leaves does not stop the others' feed, and a worker is woken per batch, not per message.

use std::sync::atomic::{AtomicUsize, Ordering};

use super::*;

/// A stand-in for the reader task: the fan-outs created, to send through.
#[derive(Default)]
struct Created(Mutex<Vec<Fanout>>);

impl Created {
    /// Creates a reader whose GUID is the number of readers created before it, in every byte.
    fn create(&self) -> impl FnOnce(Fanout) -> Result<(smol::Task<()>, Gid), NodeError> + '_ {
        move |fanout| {
            let mut created = self.0.lock().unwrap();
            let gid = Gid::from([created.len() as u8; 16]);
            created.push(fanout);
            Ok((smol::spawn(std::future::pending()), gid))
        }
    }
    fn count(&self) -> usize {
        self.0.lock().unwrap().len()
    }
    fn last(&self) -> Fanout {
        self.0.lock().unwrap().last().unwrap().clone()
    }
}

fn no_wake() -> Box<dyn Fn() + Send + Sync> {
    Box::new(|| {})
}

fn js(position: f64) -> StateMsg {
    StateMsg::JointState(Arc::new(JointState {
        name: vec!["j".into()],
        position: vec![position],
        ..Default::default()
    }))
}

fn positions(inbox: &Inbox) -> Vec<f64> {
    let mut taken = VecDeque::new();
    inbox.take(&mut taken);
    (taken.into_iter())
        .map(|(_, m)| match m {
            StateMsg::JointState(js) => js.position[0],
            StateMsg::Odometry(_) => f64::NAN,
        })
        .collect()
}

#[test]
fn the_nodes_on_one_topic_share_one_reader() {
    let (readers, created) = (StateReaders::default(), Created::default());
    let inboxes: Vec<Arc<Inbox>> = (0..4)
        .map(|_| Inbox::new(BATCH, Duration::from_secs(1)))
        .collect();
    let mut joined = Vec::new();
    for inbox in &inboxes {
        for topic in ["/joint_states", "/odom"] {
            let j = readers.join(topic, inbox.clone(), no_wake(), created.create());
            joined.push(j.unwrap());
        }
    }
    // A remapped topic of one node is its own reader.
    let other = Inbox::new(BATCH, Duration::from_secs(1));
    joined.push(
        (readers.join(
            "/arm/joint_states",
            other.clone(),
            no_wake(),
            created.create(),
        ))
        .unwrap(),
    );
    assert_eq!(created.count(), 3);
    assert_eq!(
        readers.topics(),
        vec![
            ("/arm/joint_states".to_string(), 1),
            ("/joint_states".to_string(), 4),
            ("/odom".to_string(), 4)
        ]
    );
    // One message reaches every node on its topic, and only them.
    created.0.lock().unwrap()[0].send(js(1.0));
    for inbox in &inboxes {
        assert_eq!(positions(inbox), vec![1.0]);
    }
    assert!(positions(&other).is_empty());
}

#[test]
fn a_node_that_leaves_does_not_stop_the_others() {
    let (readers, created) = (StateReaders::default(), Created::default());
    let a = Inbox::new(BATCH, Duration::from_secs(1));
    let b = Inbox::new(BATCH, Duration::from_secs(1));
    // `a` joins first: the reader is created on its node.
    let ja = readers.join("/joint_states", a.clone(), no_wake(), created.create());
    let jb = readers.join("/joint_states", b.clone(), no_wake(), created.create());
    // Both list the one reader as theirs in the graph.
    let (ja, jb) = (ja.unwrap(), jb.unwrap());
    assert_eq!(ja.reader_gid(), Gid::from([0; 16]));
    assert_eq!(jb.reader_gid(), ja.reader_gid());
    let fanout = created.last();
    drop(ja);
    fanout.send(js(2.0));
    assert!(positions(&a).is_empty(), "a left: it follows nothing");
    assert_eq!(positions(&b), vec![2.0]);
    assert_eq!(readers.topics(), vec![("/joint_states".to_string(), 1)]);
    // The last to leave removes the reader; the next to join creates one again.
    drop(jb);
    assert!(readers.topics().is_empty());
    let _ja = readers.join("/joint_states", a.clone(), no_wake(), created.create());
    assert_eq!(created.count(), 2);
    created.last().send(js(3.0));
    assert_eq!(positions(&a), vec![3.0]);
}

/// Joins an inbox whose wake takes it, as its worker does; returns the wakes and what was
/// taken.
fn worker_like(
    batch: usize,
    silence: Duration,
) -> (Fanout, Arc<AtomicUsize>, Arc<Mutex<Vec<f64>>>, Joined) {
    let (readers, created) = (StateReaders::default(), Created::default());
    let inbox = Inbox::new(batch, silence);
    let wakes = Arc::new(AtomicUsize::new(0));
    let applied = Arc::new(Mutex::new(Vec::new()));
    let wake = {
        let (inbox, wakes, applied) = (inbox.clone(), wakes.clone(), applied.clone());
        Box::new(move || {
            wakes.fetch_add(1, Ordering::SeqCst);
            applied.lock().unwrap().extend(positions(&inbox));
        })
    };
    let joined = readers
        .join("/joint_states", inbox, wake, created.create())
        .unwrap();
    (created.last(), wakes, applied, joined)
}

#[test]
fn a_worker_is_woken_per_batch_not_per_message() {
    let (fanout, wakes, applied, _joined) = worker_like(BATCH, Duration::from_secs(60));
    let n = 4 * BATCH + 1;
    for i in 0..n {
        fanout.send(js(i as f64));
    }
    // The first message (after a silence), then every BATCH after it; nothing lost, in order.
    assert_eq!(wakes.load(Ordering::SeqCst), 1 + (n - 1) / BATCH);
    let expected: Vec<f64> = (0..n).map(|i| i as f64).collect();
    assert_eq!(*applied.lock().unwrap(), expected);
}

#[test]
fn an_input_after_a_silence_wakes_the_worker_at_once() {
    let (fanout, wakes, _applied, _joined) = worker_like(BATCH, Duration::from_millis(5));
    fanout.send(js(0.0));
    fanout.send(js(1.0));
    assert_eq!(wakes.load(Ordering::SeqCst), 1);
    std::thread::sleep(Duration::from_millis(20));
    fanout.send(js(2.0));
    assert_eq!(wakes.load(Ordering::SeqCst), 2);
}

#[test]
fn under_sim_time_every_message_wakes_the_worker() {
    let (fanout, wakes, applied, _joined) = worker_like(1, Duration::from_secs(60));
    for i in 0..5 {
        fanout.send(js(i as f64));
    }
    assert_eq!(wakes.load(Ordering::SeqCst), 5);
    assert_eq!(applied.lock().unwrap().len(), 5);
}

#[test]
fn a_full_inbox_drops_the_newest_and_counts_every_arrival() {
    let inbox = Inbox::new(BATCH, Duration::from_secs(60));
    for i in 0..CAPACITY + 10 {
        inbox.push(js(i as f64), Time::now(), Instant::now());
    }
    assert_eq!(inbox.counts().0, (CAPACITY + 10) as u64);
    let taken = positions(&inbox);
    assert_eq!(taken.len(), CAPACITY);
    assert_eq!(taken.last(), Some(&((CAPACITY - 1) as f64)));
}
