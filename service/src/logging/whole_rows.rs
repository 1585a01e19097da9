//! The check that a `signals.csv` holds whole rows only: after a full disk, a crash or a
//! kill, the writer's promise is that the file ends at a row boundary and every row has the
//! header's number of fields (docs/outputs.md). A reader (or a test) checks it here.

/// The `seq` column of a `signals.csv` text whose rows are all whole: the text ends with a
/// line end, every row has the header's number of fields, the first holds a sequence
/// number and every field after the four leading ones is a number.
///
/// # Errors
///
/// The first torn or malformed row, quoted.
pub fn whole_rows(text: &str) -> Result<Vec<u64>, String> {
    if !text.ends_with('\n') {
        let tail: String = {
            let last: Vec<char> = text.chars().rev().take(80).collect();
            last.into_iter().rev().collect()
        };
        return Err(format!("ends in a torn row: {tail:?}"));
    }
    let mut lines = text.lines();
    let columns = lines.next().ok_or("has no header")?.split(',').count();
    lines
        .map(|l| {
            let fields: Vec<&str> = l.split(',').collect();
            if fields.len() != columns {
                return Err(format!(
                    "torn row {l:?}: {} fields, the header has {columns}",
                    fields.len()
                ));
            }
            if let Some(f) = fields.iter().skip(4).find(|f| f.parse::<f64>().is_err()) {
                return Err(format!("field {f:?} of {l:?} is not a number"));
            }
            fields[0]
                .parse()
                .map_err(|e| format!("seq {:?} of {l:?}: {e}", fields[0]))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::whole_rows;

    #[test]
    fn whole_rows_pass_and_a_torn_one_is_quoted() {
        let good = "seq,t,a,b,y0\n1,0,x,y,0.5\n2,0,x,y,-1e300\n";
        assert_eq!(whole_rows(good), Ok(vec![1, 2]));
        assert!(
            whole_rows("seq,t,a,b,y0\n1,0,x,y,0.5\n2,0")
                .unwrap_err()
                .contains("torn")
        );
        assert!(
            whole_rows("seq,t,a,b,y0\n1,0,x,y\n")
                .unwrap_err()
                .contains("torn row")
        );
        assert!(
            whole_rows("seq,t,a,b,y0\n1,0,x,y,z\n")
                .unwrap_err()
                .contains("not a number")
        );
    }
}
