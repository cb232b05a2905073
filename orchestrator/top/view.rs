//! `glint top`'s screen (ratatui over crossterm) and its one-shot text form.

use anyhow::Result;
use ratatui::crossterm::event::{self, Event, KeyCode, KeyEventKind, KeyModifiers};
use ratatui::layout::{Constraint, Layout};
use ratatui::style::{Modifier, Style};
use ratatui::text::Line;
use ratatui::widgets::{Block, Paragraph, Row, Table};

use super::model::ServiceRow;
use super::{Snapshot, Watch, REFRESH};

const HEADER: [&str; 11] = [
    "service", "state", "pid", "restarts", "in/s", "out/s", "p50 µs", "p99 µs", "dropped", "CPU %",
    "RSS MiB",
];

fn or_dash(v: Option<f64>, decimals: usize) -> String {
    v.map_or("–".to_string(), |x| format!("{x:.decimals$}"))
}

/// One service's cells, in [`HEADER`]'s order.
fn cells(r: &ServiceRow) -> [String; 11] {
    let dropped = if r.dropped.is_empty() {
        "0".to_string()
    } else {
        (r.dropped.iter())
            .map(|(k, n)| format!("{k} {n}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    [
        r.name.clone(),
        r.state.clone(),
        r.pid.to_string(),
        r.restarts.to_string(),
        format!("{:.0}", r.inputs_per_s),
        format!("{:.0}", r.outputs_per_s),
        or_dash(r.latency_p50_us, 0),
        or_dash(r.latency_p99_us, 0),
        dropped,
        or_dash(r.cpu_percent, 0),
        or_dash(r.rss_mib, 1),
    ]
}

/// The snapshot as a plain table (`glint top --once`).
pub fn text(s: &Snapshot) -> String {
    let rows: Vec<[String; 11]> = s.services.iter().map(cells).collect();
    let widths: Vec<usize> = (0..HEADER.len())
        .map(|i| {
            (rows.iter().map(|r| r[i].chars().count()))
                .chain([HEADER[i].chars().count()])
                .max()
                .unwrap_or(0)
        })
        .collect();
    let line = |cols: Vec<&str>| {
        let padded: Vec<String> = (cols.iter().zip(&widths))
            .map(|(c, w)| format!("{c:<w$}"))
            .collect();
        padded.join("  ").trim_end().to_string() + "\n"
    };
    let mut out = format!("{}: {}\n", s.prefix, s.nodes.join(", "));
    out += &line(HEADER.to_vec());
    for r in &rows {
        out += &line(r.iter().map(String::as_str).collect());
    }
    out
}

/// The live screen until `q`, Esc or Ctrl-C.
pub fn interactive(prefix: &str) -> Result<()> {
    let mut watch = Watch::open(prefix)?;
    let mut terminal = ratatui::init();
    let result = (|| -> Result<()> {
        loop {
            watch.poll()?;
            let snap = watch.snapshot();
            terminal.draw(|f| draw(f, &snap))?;
            if event::poll(REFRESH)? {
                if let Event::Key(k) = event::read()? {
                    let ctrl_c =
                        k.code == KeyCode::Char('c') && k.modifiers.contains(KeyModifiers::CONTROL);
                    let quit = matches!(k.code, KeyCode::Char('q') | KeyCode::Esc) || ctrl_c;
                    if k.kind == KeyEventKind::Press && quit {
                        return Ok(());
                    }
                }
            }
        }
    })();
    ratatui::restore();
    result
}

fn draw(f: &mut ratatui::Frame, s: &Snapshot) {
    let [title, table, foot] = Layout::vertical([
        Constraint::Length(1),
        Constraint::Min(3),
        Constraint::Length(1),
    ])
    .areas(f.area());
    let state = if s.nodes.is_empty() {
        "ended".to_string()
    } else {
        format!("{} nodes", s.nodes.len())
    };
    f.render_widget(
        Paragraph::new(Line::from(format!("glint top  {}  {state}", s.prefix)))
            .style(Style::new().add_modifier(Modifier::BOLD)),
        title,
    );
    let rows: Vec<Row> = s.services.iter().map(|r| Row::new(cells(r))).collect();
    let widths = [
        Constraint::Length(12),
        Constraint::Length(9),
        Constraint::Length(8),
        Constraint::Length(8),
        Constraint::Length(7),
        Constraint::Length(7),
        Constraint::Length(7),
        Constraint::Length(7),
        Constraint::Min(10),
        Constraint::Length(6),
        Constraint::Length(8),
    ];
    f.render_widget(
        Table::new(rows, widths)
            .header(Row::new(HEADER).style(Style::new().add_modifier(Modifier::UNDERLINED)))
            .block(Block::bordered().title(" services ")),
        table,
    );
    f.render_widget(
        Paragraph::new(format!(
            "heartbeats and /proc every {} ms; latency: input send → processed; q quits",
            REFRESH.as_millis()
        )),
        foot,
    );
}
