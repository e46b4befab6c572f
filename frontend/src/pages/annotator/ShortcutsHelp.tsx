export const SHORTCUTS: [string, string][] = [
  ["Space", "play / pause"],
  ["← / →", "step one frame"],
  ["Shift + ← / →", "step ten frames"],
  ["Home / End", "first / last frame"],
  ["I / O", "set in / out point at the playhead"],
  ["1 … 9", "label the in–out span (or the selected segment) with a quick label"],
  ["/", "search all labels; ↓ ↑ choose a match, Enter applies it (or the only match)"],
  ["Delete", "delete the selected segment"],
  ["Ctrl + Z", "undo"],
  ["Ctrl + Shift + Z", "redo"],
  ["[ / ]", "slower / faster (0.25x – 4x)"],
  ["V", "RGB picture on / skeleton only"],
  ["B", "blur the head on / off (annotators)"],
  ["Ctrl + Enter", "submit your drafts for review"],
  ["Esc", "clear in / out, close this list"],
  ["?", "show / hide this list"],
];

export function ShortcutsHelp({ onClose }: { onClose: () => void }) {
  return (
    <div className="shortcuts" role="dialog" aria-label="Keyboard shortcuts">
      <h2>Keyboard shortcuts</h2>
      <table>
        <tbody>
          {SHORTCUTS.map(([keys, what]) => (
            <tr key={keys}>
              <th><kbd>{keys}</kbd></th>
              <td>{what}</td>
            </tr>
          ))}
        </tbody>
      </table>
      <button type="button" onClick={onClose}>Close</button>
    </div>
  );
}
